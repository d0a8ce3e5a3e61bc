// The deskew record of a run's stats.json (io/run_deskew_record.hpp): the sweep model written by
// sweep_record_json() reads back exactly; runs that did not deskew, or deskewed by the scans'
// own times, carry no sweep; damaged records are refused with messages naming the file.
#include <gtest/gtest.h>

#include <string>

#include "shine/core/error.hpp"
#include "shine/io/run_deskew_record.hpp"

namespace shine {
namespace {

constexpr const char* kSource = "out/stats.json";

std::string stats_with(const std::string& deskew) { return "{\"deskew\": " + deskew + "}"; }

std::string error_of(const std::string& text) {
    try {
        read_run_deskew_record(text, kSource);
    } catch (const DataError& e) {
        return e.what();
    }
    return "";
}

TEST(RunDeskewRecord, TheSweepModelReadsBackExactly) {
    SweepTimeModel model;
    model.direction = SweepDirection::kCounterClockwise;
    model.start_azimuth_deg = 93.25;
    model.pose_azimuth_deg = -12.5;
    model.sweep_period_s = 0.05;
    const std::string text = stats_with(
        "{\"active\": true, \"scan_period_s\": 0.05, \"point_time\": {\"field\": "
        "\"azimuth\"}, \"sweep\": " +
        sweep_record_json(model) + "}");
    const RunDeskewRecord record = read_run_deskew_record(text, kSource);
    EXPECT_TRUE(record.active);
    EXPECT_EQ(record.scan_period_s, 0.05);
    ASSERT_TRUE(record.sweep.has_value());
    EXPECT_EQ(record.sweep->direction, model.direction);
    EXPECT_EQ(record.sweep->start_azimuth_deg, model.start_azimuth_deg);
    EXPECT_EQ(record.sweep->pose_azimuth_deg, model.pose_azimuth_deg);
    EXPECT_EQ(record.sweep->sweep_period_s, model.sweep_period_s);
}

TEST(RunDeskewRecord, RunsWithoutAzimuthTimesCarryNoSweep) {
    EXPECT_FALSE(read_run_deskew_record("{}", kSource).active);
    EXPECT_FALSE(read_run_deskew_record(stats_with("{\"active\": false}"), kSource).active);
    const RunDeskewRecord own_times = read_run_deskew_record(
        stats_with("{\"active\": true, \"point_time\": {\"field\": \"t\"}}"), kSource);
    EXPECT_TRUE(own_times.active);
    EXPECT_EQ(own_times.scan_period_s, 0.1);
    EXPECT_FALSE(own_times.sweep.has_value());
}

TEST(RunDeskewRecord, DamagedRecordsAreRefusedNamingTheFile) {
    const std::string azimuth = "\"active\": true, \"point_time\": {\"field\": \"azimuth\"}";
    const std::string good_sweep =
        "\"direction\": \"clockwise\", \"start_azimuth_deg\": 180, \"pose_azimuth_deg\": 0";
    const struct {
        std::string text;
        std::string says;
    } cases[] = {
        {"{\"deskew\": ", "is not valid JSON"},
        {"[1, 2]", "is not a JSON object"},
        {stats_with("3"), "deskew is not an object"},
        {stats_with("{\"active\": \"yes\"}"), "type must be boolean"},
        {stats_with("{\"active\": true, \"scan_period_s\": -0.1}"), "scan_period_s"},
        {stats_with("{" + azimuth + "}"), "no deskew.sweep"},
        {stats_with("{" + azimuth + ", \"sweep\": []}"), "deskew.sweep is not an object"},
        {stats_with("{" + azimuth + ", \"sweep\": {" + good_sweep + "}}"), "period_s"},
        {stats_with("{" + azimuth + ", \"sweep\": {" + good_sweep + ", \"period_s\": 0}}"),
         "period_s is not a positive number"},
        {stats_with("{" + azimuth +
                    ", \"sweep\": {\"direction\": \"up\", \"start_azimuth_deg\": 180, "
                    "\"pose_azimuth_deg\": 0, \"period_s\": 0.1}}"),
         "clockwise"},
    };
    for (const auto& c : cases) {
        const std::string message = error_of(c.text);
        EXPECT_NE(message.find(kSource), std::string::npos) << c.text << " -> " << message;
        EXPECT_NE(message.find(c.says), std::string::npos) << c.text << " -> " << message;
    }
}

}  // namespace
}  // namespace shine
