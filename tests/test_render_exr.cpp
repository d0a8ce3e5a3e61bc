// EXR images round-trip through OpenEXR's own API: written by write_exr, read back with
// Imf::InputFile, every value (NaN and infinities included) is equal bit for bit.
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfStringAttribute.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <random>

#include "shine/core/error.hpp"
#include "shine/render/exr_image.hpp"

namespace shine {
namespace {
namespace fs = std::filesystem;

fs::path test_dir() {
    const fs::path d = fs::path(SHINE_TEST_TMP_DIR) / "render_exr" /
                       ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::remove_all(d);
    fs::create_directories(d);
    return d;
}

std::uint32_t bits(float v) {
    std::uint32_t b;
    std::memcpy(&b, &v, sizeof(b));
    return b;
}

ExrImage make_image(int width, int height) {
    ExrImage image(width, height);
    std::mt19937 rng(7);
    std::normal_distribution<float> normal(0.0f, 10.0f);
    for (const char* name : {"range", "normal.X", "normal.Y", "normal.Z", "error"}) {
        std::vector<float> values(image.num_pixels());
        for (float& v : values) v = normal(rng);
        values[0] = std::numeric_limits<float>::quiet_NaN();
        values[1] = std::numeric_limits<float>::infinity();
        values[2] = -0.0f;
        values[3] = std::numeric_limits<float>::denorm_min();
        image.add_channel(name, std::move(values));
    }
    image.attributes["shine_units"] = "metres";
    return image;
}

TEST(RenderExr, RoundTripsThroughOpenExrApiBitForBit) {
    const fs::path path = test_dir() / "image.exr";
    const ExrImage image = make_image(37, 11);
    write_exr(path, image);

    Imf::InputFile file(path.c_str());
    const Imath::Box2i window = file.header().dataWindow();
    ASSERT_EQ(window.max.x - window.min.x + 1, 37);
    ASSERT_EQ(window.max.y - window.min.y + 1, 11);
    std::vector<std::string> names;
    for (auto it = file.header().channels().begin(); it != file.header().channels().end(); ++it) {
        names.push_back(it.name());
        EXPECT_EQ(it.channel().type, Imf::FLOAT) << it.name();
    }
    // OpenEXR lists channels sorted by name.
    EXPECT_EQ(names,
              (std::vector<std::string>{"error", "normal.X", "normal.Y", "normal.Z", "range"}));
    const auto* units = file.header().findTypedAttribute<Imf::StringAttribute>("shine_units");
    ASSERT_NE(units, nullptr);
    EXPECT_EQ(units->value(), "metres");

    std::map<std::string, std::vector<float>> read;
    Imf::FrameBuffer frame;
    for (const std::string& name : names) {
        read[name].resize(image.num_pixels());
        frame.insert(name, Imf::Slice(Imf::FLOAT, reinterpret_cast<char*>(read[name].data()),
                                      sizeof(float), sizeof(float) * 37));
    }
    file.setFrameBuffer(frame);
    file.readPixels(window.min.y, window.max.y);
    for (const std::string& name : names) {
        const std::vector<float>& expected = image.channel(name);
        for (std::size_t i = 0; i < expected.size(); ++i) {
            ASSERT_EQ(bits(read[name][i]), bits(expected[i])) << name << " pixel " << i;
        }
    }
}

TEST(RenderExr, ReadExrGivesBackChannelsAndAttributes) {
    const fs::path path = test_dir() / "image.exr";
    const ExrImage image = make_image(5, 3);
    write_exr(path, image);
    const ExrImage back = read_exr(path);
    EXPECT_EQ(back.width(), 5);
    EXPECT_EQ(back.height(), 3);
    EXPECT_EQ(back.attributes.at("shine_units"), "metres");
    for (const std::string& name : image.channel_names()) {
        ASSERT_TRUE(back.has_channel(name)) << name;
        const std::vector<float>& a = image.channel(name);
        const std::vector<float>& b = back.channel(name);
        for (std::size_t i = 0; i < a.size(); ++i) ASSERT_EQ(bits(a[i]), bits(b[i]));
    }
}

TEST(RenderExr, ErrorsNameTheFileAndLeaveNothing) {
    const fs::path dir = test_dir();
    try {
        read_exr(dir / "missing.exr");
        FAIL() << "read a missing file";
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("missing.exr"), std::string::npos) << e.what();
    }
    const fs::path not_exr = dir / "not.exr";
    std::ofstream(not_exr) << "ply\nformat ascii 1.0\n";
    try {
        read_exr(not_exr);
        FAIL() << "read a text file as EXR";
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("not.exr"), std::string::npos) << e.what();
    }
    // A write into a missing directory fails, naming the file; no temporary is left behind.
    EXPECT_THROW(write_exr(dir / "no_such_dir" / "x.exr", make_image(2, 2)), IoError);
    EXPECT_THROW(write_exr(dir / "empty.exr", ExrImage(2, 2)), DataError);
    EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);  // not.exr
    ExrImage image(2, 2);
    EXPECT_THROW(image.add_channel("range", std::vector<float>(3)), DataError);
    image.add_channel("range", std::vector<float>(4));
    EXPECT_THROW(image.add_channel("range", std::vector<float>(4)), DataError);
    EXPECT_THROW(image.channel("error"), DataError);
}

}  // namespace
}  // namespace shine
