// The binary records of ShineVDB's state files: what is written reads back exactly, and every
// kind of damage (truncation, a wrong section, an impossible length, another element size,
// trailing bytes) is an IoError naming the file, the byte offset and the record.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "shine/core/error.hpp"
#include "shine/io/binary_stream.hpp"

namespace fs = std::filesystem;
using shine::BinaryReader;
using shine::BinaryWriter;

namespace {

/// Each test writes files of its own names: ctest runs the tests of this file as parallel
/// processes.
fs::path write_file(const std::string& name, const std::string& bytes) {
    const fs::path dir = fs::path(SHINE_TEST_TMP_DIR) / "binary_stream";
    fs::create_directories(dir);
    const fs::path path = dir / name;
    std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
    return path;
}

std::string sample_records() {
    std::ostringstream stream;
    BinaryWriter out(stream);
    out.tag("header");
    out.value<std::uint32_t>(7);
    out.value(2.5);
    out.string("run description");
    out.array(std::vector<float>{1.0f, -2.0f, 3.5f});
    out.array(std::vector<std::uint16_t>{});
    return stream.str();
}

/// The IoError message of `read`, or "" if it did not throw.
template <class F>
std::string error_of(F read) {
    try {
        read();
    } catch (const shine::IoError& e) {
        return e.what();
    }
    return {};
}

}  // namespace

TEST(BinaryStream, RecordsReadBackExactly) {
    BinaryReader in(write_file("records.bin", sample_records()), "state");
    EXPECT_TRUE(in.next_is_tag("header"));
    EXPECT_FALSE(in.next_is_tag("head"));
    in.expect_tag("header");
    EXPECT_EQ(in.value<std::uint32_t>("count"), 7u);
    EXPECT_EQ(in.value<double>("scale"), 2.5);
    EXPECT_EQ(in.string("text"), "run description");
    std::vector<float> floats(3);
    in.array_into(floats.data(), floats.size(), "floats");
    EXPECT_EQ(floats, (std::vector<float>{1.0f, -2.0f, 3.5f}));
    EXPECT_TRUE(in.array<std::uint16_t>("empty").empty());
    in.expect_end();
}

TEST(BinaryStream, EveryTruncationIsReportedWithFileAndOffset) {
    const std::string whole = sample_records();
    for (std::size_t cut = 1; cut < whole.size(); ++cut) {
        const fs::path path = write_file("cut.bin", whole.substr(0, cut));
        const std::string message = error_of([&] {
            BinaryReader in(path, "state");
            in.expect_tag("header");
            in.value<std::uint32_t>("count");
            in.value<double>("scale");
            in.string("text");
            std::vector<float> floats(3);
            in.array_into(floats.data(), floats.size(), "floats");
            in.array<std::uint16_t>("empty");
        });
        ASSERT_NE(message.find("state '" + path.string() + "', byte "), std::string::npos)
            << "cut at " << cut << ": " << message;
        EXPECT_NE(message.find("truncated"), std::string::npos) << message;
    }
}

TEST(BinaryStream, WrongSectionSizeAndTrailingBytesAreReported) {
    const fs::path path = write_file("good.bin", sample_records());
    EXPECT_NE(error_of([&] {
                  BinaryReader in(path, "state");
                  in.expect_tag("footer");
              }).find("section 'footer' expected, found 'header'"),
              std::string::npos);
    // The float array read as doubles: the element size differs.
    EXPECT_NE(error_of([&] {
                  BinaryReader in(path, "state");
                  in.expect_tag("header");
                  in.value<std::uint32_t>("count");
                  in.value<double>("scale");
                  in.string("text");
                  in.array<double>("values");
              }).find("values has 4-byte values, expected 8"),
              std::string::npos);
    // Three floats where four were expected.
    EXPECT_NE(error_of([&] {
                  BinaryReader in(path, "state");
                  in.expect_tag("header");
                  in.value<std::uint32_t>("count");
                  in.value<double>("scale");
                  in.string("text");
                  std::vector<float> four(4);
                  in.array_into(four.data(), four.size(), "features");
              }).find("features holds 3 values, expected 4"),
              std::string::npos);
    const fs::path longer = write_file("longer.bin", sample_records() + "xy");
    EXPECT_NE(error_of([&] {
                  BinaryReader in(longer, "state");
                  in.expect_tag("header");
                  in.value<std::uint32_t>("count");
                  in.value<double>("scale");
                  in.string("text");
                  in.array<float>("floats");
                  in.array<std::uint16_t>("empty");
                  in.expect_end();
              }).find("2 unexpected bytes"),
              std::string::npos);
}

TEST(BinaryStream, ImpossibleLengthsDoNotAllocate) {
    std::ostringstream stream;
    BinaryWriter out(stream);
    out.value<std::uint64_t>(~0ull);  // a string "of 16 EiB"
    const fs::path path = write_file("huge.bin", stream.str());
    const std::string message = error_of([&] {
        BinaryReader in(path, "state");
        in.string("name");
    });
    EXPECT_NE(message.find("name claims 18446744073709551615 bytes"), std::string::npos) << message;
}

TEST(BinaryStream, MissingAndEmptyFilesAreReported) {
    EXPECT_NE(error_of([] {
                  BinaryReader in("/nonexistent/state.bin", "state");
              }).find("/nonexistent/state.bin"),
              std::string::npos);
    const fs::path empty = write_file("empty.bin", "");
    EXPECT_NE(error_of([&] { BinaryReader in(empty, "state"); }).find("empty"), std::string::npos);
}
