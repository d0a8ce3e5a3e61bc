// ExposureTrack: a held-out image's exposure read off the mapped images' gains of its camera;
// the gains as stats.json records them.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "shine/colour/camera_exposure.hpp"
#include "shine/colour/exposure_record.hpp"
#include "shine/core/error.hpp"

namespace shine {
namespace {

TEST(ExposureTrack, InterpolatesTheLogGainBetweenTheMappedFramesAround) {
    // Out of order, two cameras.
    const ExposureTrack track(
        {{"image_00", 6, 1.2}, {"image_00", 0, 0.9}, {"image_00", 3, 1.0}, {"side", 3, 2.0}});
    EXPECT_DOUBLE_EQ(track.gain_at("image_00", 0), 0.9);
    EXPECT_DOUBLE_EQ(track.gain_at("image_00", 3), 1.0);
    // A third of the way from frame 3 to 6: exp(2/3 ln 1 + 1/3 ln 1.2).
    EXPECT_NEAR(track.gain_at("image_00", 4), std::pow(1.2, 1.0 / 3.0), 1e-12);
    EXPECT_NEAR(track.gain_at("image_00", 1), std::exp((2.0 * std::log(0.9)) / 3.0), 1e-12);
    // Beyond the mapped frames: the nearest one's gain.
    EXPECT_DOUBLE_EQ(track.gain_at("image_00", 9), 1.2);
    EXPECT_DOUBLE_EQ(track.gain_at("side", 0), 2.0);
    EXPECT_DOUBLE_EQ(track.gain_at("side", 7), 2.0);
    // A camera without gains, or an empty track: no change.
    EXPECT_DOUBLE_EQ(track.gain_at("rear", 3), 1.0);
    EXPECT_DOUBLE_EQ(ExposureTrack().gain_at("image_00", 3), 1.0);
    EXPECT_EQ(track.gains().size(), 4u);
}

TEST(ExposureTrack, AFrameGivenTwiceKeepsTheLastGain) {
    const ExposureTrack track({{"c", 2, 1.5}, {"c", 2, 0.5}, {"c", 1, 1.0}});
    EXPECT_EQ(track.gains().size(), 2u);
    EXPECT_DOUBLE_EQ(track.gain_at("c", 2), 0.5);
}

TEST(ExposureTrack, RejectsAGainThatIsNotFiniteAndPositive) {
    for (const double bad : {0.0, -1.0, std::numeric_limits<double>::quiet_NaN(),
                             std::numeric_limits<double>::infinity()}) {
        EXPECT_THROW(ExposureTrack({{"c", 0, 1.0}, {"c", 1, bad}}), DataError) << bad;
    }
}

TEST(ExposureRecord, RoundTripsThroughAStatsJson) {
    const ExposureTrack track({{"image_00", 0, 1.048}, {"image_00", 3, 0.96}, {"side", 1, 1.25}});
    const std::string stats = R"({"heldout": {}, "appearance": {"colour": true, "exposure": )" +
                              exposure_record_json(track) + "}}";
    const ExposureTrack read = read_exposure_record(stats, "stats.json");
    ASSERT_EQ(read.gains().size(), 3u);
    for (std::size_t k = 0; k < 3; ++k) {
        EXPECT_EQ(read.gains()[k].camera, track.gains()[k].camera);
        EXPECT_EQ(read.gains()[k].frame, track.gains()[k].frame);
        EXPECT_DOUBLE_EQ(read.gains()[k].gain, track.gains()[k].gain);
    }
    // Runs without images, or older ones: no gains, every camera as fitted.
    EXPECT_TRUE(read_exposure_record(R"({"heldout": {}})", "stats.json").empty());
    EXPECT_TRUE(read_exposure_record(R"({"appearance": {"colour": false}})", "s").empty());
}

TEST(ExposureRecord, DamagedRecordsNameTheFile) {
    for (const char* bad :
         {"", "[1, 2]", "{\"appearance\": 3}", "{\"appearance\": {\"exposure\": {}}}",
          "{\"appearance\": {\"exposure\": [5]}}",
          "{\"appearance\": {\"exposure\": [{\"camera\": \"c\", \"frame\": -1, \"gain\": 1}]}}",
          "{\"appearance\": {\"exposure\": [{\"camera\": \"c\", \"frame\": 0}]}}",
          "{\"appearance\": {\"exposure\": [{\"camera\": \"c\", \"frame\": 0, \"gain\": 0}]}}",
          "{\"appearance\": {\"exposure\": [{\"camera\": 7, \"frame\": 0, \"gain\": 1}]}}",
          "{\"appearance\": {\"exposure\": [{\"camera\": \"c\", \"frame\": 0, \"gain\": "
          "1e999}]}}"}) {
        try {
            read_exposure_record(bad, "out/stats.json");
            ADD_FAILURE() << "accepted: " << bad;
        } catch (const DataError& e) {
            EXPECT_NE(std::string(e.what()).find("out/stats.json"), std::string::npos) << e.what();
        }
    }
}

}  // namespace
}  // namespace shine
