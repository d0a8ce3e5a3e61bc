// Per-point times: every field name and unit, in PLY and PCD scans, and the rules that turn
// them into seconds relative to the scan (io/point_times.hpp).
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/io/pcd.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/point_times.hpp"

namespace fs = std::filesystem;

namespace {

using shine::PointTimeFormat;

constexpr double kExactS = 1e-12;      // values that are exact in double
constexpr double kFloat32S = 1e-8;     // a float32 time of up to 0.1 s
constexpr double kAbsoluteNsS = 1e-6;  // absolute ns through a double: ~256 ns steps

/// An ascii PLY scan of three points whose time property is `type name` with the values `times`.
std::string ply_with_time(const std::string& type, const std::string& name,
                          const std::vector<std::string>& times) {
    std::string text = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(times.size()) +
                       "\nproperty float x\nproperty " + type + " " + name +
                       "\nproperty float y\nproperty float z\nend_header\n";
    for (std::size_t i = 0; i < times.size(); ++i) {
        text += std::to_string(i) + " " + times[i] + " 2 3\n";
    }
    return text;
}

std::string pcd_with_time(const std::string& name, const std::string& type, const std::string& size,
                          const std::vector<std::string>& times) {
    const std::string n = std::to_string(times.size());
    std::string text = "VERSION 0.7\nFIELDS x y z intensity " + name + "\nSIZE 4 4 4 4 " + size +
                       "\nTYPE F F F F " + type + "\nCOUNT 1 1 1 1 1\nWIDTH " + n +
                       "\nHEIGHT 1\nPOINTS " + n + "\nDATA ascii\n";
    for (std::size_t i = 0; i < times.size(); ++i) {
        text += std::to_string(i) + " 2 3 7 " + times[i] + "\n";
    }
    return text;
}

}  // namespace

TEST(PointTimes, IntegersAreNanosecondsAndSmallFloatsSeconds) {
    PointTimeFormat format;
    auto t = shine::point_times_relative_s({0.0, 5e7, 1e8}, /*integer_type=*/true, {}, &format);
    EXPECT_NEAR(t[1], 0.05, kExactS);
    EXPECT_NEAR(t[2], 0.1, kExactS);
    EXPECT_TRUE(format.nanoseconds);
    EXPECT_FALSE(format.absolute);

    t = shine::point_times_relative_s({-0.1, -0.05, 0.0}, false, {}, &format);
    EXPECT_NEAR(t[0], -0.1, kExactS);
    EXPECT_FALSE(format.nanoseconds);
    EXPECT_FALSE(format.absolute);
}

TEST(PointTimes, FloatsSpanningMoreThanASweepAreNanoseconds) {
    PointTimeFormat format;
    const auto t = shine::point_times_relative_s({0.0, 2.5e7, 9.9e7}, false, {}, &format);
    EXPECT_TRUE(format.nanoseconds);
    EXPECT_NEAR(t[2], 0.099, kExactS);
}

TEST(PointTimes, AbsoluteTimesLoseTheStampOrTheEarliestPoint) {
    PointTimeFormat format;
    format.field = "timestamp";
    // Seconds since the epoch, float64: the stamp is subtracted when there is one.
    auto t = shine::point_times_relative_s({1.7e9 + 0.02, 1.7e9 + 0.07}, false, 1.7e9, &format);
    EXPECT_TRUE(format.absolute);
    EXPECT_TRUE(format.from_stamp);
    EXPECT_NEAR(t[0], 0.02, 1e-6);
    EXPECT_NEAR(t[1], 0.07, 1e-6);
    // Without a stamp, t = 0 is the earliest point.
    t = shine::point_times_relative_s({1.7e9 + 0.07, 1.7e9 + 0.02}, false, {}, &format);
    EXPECT_FALSE(format.from_stamp);
    EXPECT_NEAR(t[0], 0.05, 1e-6);
    EXPECT_NEAR(t[1], 0.0, 1e-6);
    EXPECT_NE(format.describe().find("absolute"), std::string::npos) << format.describe();
    // Nanoseconds since the epoch (uint64 in PCD).
    t = shine::point_times_relative_s({1.7e18, 1.7e18 + 6.4e7}, true, {}, &format);
    EXPECT_TRUE(format.nanoseconds);
    EXPECT_TRUE(format.absolute);
    EXPECT_NEAR(t[1], 0.064, kAbsoluteNsS);
}

TEST(PointTimes, PlyReadsEveryFieldNameAndUnit) {
    struct Case {
        std::string type, name;
        std::vector<std::string> stored;
        double expected_last_s;
        bool nanoseconds, absolute;
        double tolerance_s;
    };
    const std::vector<Case> cases = {
        {"float", "t", {"0", "0.05", "0.1"}, 0.1, false, false, kFloat32S},
        {"double", "time", {"-0.1", "-0.05", "0"}, 0.0, false, false, kExactS},
        {"uint", "t", {"0", "50000000", "100000000"}, 0.1, true, false, kExactS},
        {"uint32", "offset_time", {"0", "40000000", "80000000"}, 0.08, true, false, kExactS},
        {"double",
         "timestamp",
         {"1700000000.00", "1700000000.03", "1700000000.09"},
         0.09,
         false,
         true,
         1e-6},
        {"int", "time", {"0", "1000", "2000"}, 2e-6, true, false, kExactS},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.type + " " + c.name);
        const shine::TimedPoints scan =
            shine::parse_ply_scan(ply_with_time(c.type, c.name, c.stored), "scan.ply");
        ASSERT_EQ(scan.points_sensor.size(), 3u);
        ASSERT_EQ(scan.point_time_s.size(), 3u);
        EXPECT_EQ(scan.points_sensor[2], Eigen::Vector3f(2, 2, 3));  // the time is not a coordinate
        EXPECT_NEAR(scan.point_time_s[2], c.expected_last_s, c.tolerance_s);
        EXPECT_EQ(scan.time_format.field, c.name);
        EXPECT_EQ(scan.time_format.nanoseconds, c.nanoseconds);
        EXPECT_EQ(scan.time_format.absolute, c.absolute);
    }
}

TEST(PointTimes, PlyPrefersTAndLeavesScansWithoutTimesEmpty) {
    const std::string both =
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty double timestamp\nproperty float x\n"
        "property float y\nproperty float z\nproperty float t\nend_header\n5 1 2 3 0.04\n";
    const shine::TimedPoints scan = shine::parse_ply_scan(both, "both.ply");
    EXPECT_EQ(scan.time_format.field, "t");
    EXPECT_NEAR(scan.point_time_s.at(0), 0.04, kFloat32S);

    const shine::TimedPoints plain =
        shine::parse_ply_scan(ply_with_time("float", "intensity", {"1", "2"}), "plain.ply");
    EXPECT_TRUE(plain.point_time_s.empty());
    EXPECT_TRUE(plain.time_format.field.empty());
}

TEST(PointTimes, PlyScanWriterRoundTrips) {
    const fs::path dir = fs::path(SHINE_TEST_TMP_DIR) / "io_point_times";
    fs::create_directories(dir);
    const std::vector<Eigen::Vector3f> points = {{1, 2, 3}, {4, 5, 6}, {-7, 8, 9.5f}};
    const std::vector<double> times = {0.0, 0.0123, 0.0999};
    shine::write_ply_scan(dir / "scan.ply", points, times);
    const shine::TimedPoints back = shine::read_ply_scan(dir / "scan.ply");
    EXPECT_EQ(back.points_sensor, points);
    ASSERT_EQ(back.point_time_s.size(), 3u);
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(back.point_time_s[i], times[i], kFloat32S);
    EXPECT_EQ(back.time_format.field, "t");
    EXPECT_EQ(back.time_format.type, "float32");
    // read_ply_points still reads the positions only.
    EXPECT_EQ(shine::read_ply_points(dir / "scan.ply"), points);
    EXPECT_THROW(shine::write_ply_scan(dir / "bad.ply", points, {0.0}), shine::DataError);
}

TEST(PointTimes, PcdReadsEveryFieldNameAndUnitInAsciiAndBinary) {
    struct Case {
        std::string name, type, size;
        std::vector<std::string> stored;
        double expected_last_s;
        bool nanoseconds, absolute;
    };
    const std::vector<Case> cases = {
        {"t", "U", "4", {"0", "30000000", "90000000"}, 0.09, true, false},
        {"time", "F", "4", {"-0.1", "-0.04", "0"}, 0.0, false, false},
        {"timestamp",
         "F",
         "8",
         {"1700000000.5", "1700000000.52", "1700000000.58"},
         0.08,
         false,
         true},
        {"offset_time", "U", "8", {"0", "10", "100000000"}, 0.1, true, false},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name + " " + c.type + c.size);
        const shine::TimedPoints scan =
            shine::parse_pcd_scan(pcd_with_time(c.name, c.type, c.size, c.stored), "scan.pcd");
        ASSERT_EQ(scan.point_time_s.size(), 3u);
        EXPECT_NEAR(scan.point_time_s[2], c.expected_last_s, 1e-6);
        EXPECT_EQ(scan.time_format.field, c.name);
        EXPECT_EQ(scan.time_format.nanoseconds, c.nanoseconds);
        EXPECT_EQ(scan.time_format.absolute, c.absolute);
        EXPECT_EQ(scan.points_sensor[1], Eigen::Vector3f(1, 2, 3));
    }
    // Binary: x y z float32, offset_time uint32 nanoseconds (Livox).
    std::string binary =
        "VERSION 0.7\nFIELDS x y z offset_time\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n"
        "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n";
    for (int i = 0; i < 2; ++i) {
        const float xyz[3] = {1.0f * i, 2.0f, 3.0f};
        const std::uint32_t ns = 70000000u * static_cast<std::uint32_t>(i);
        binary.append(reinterpret_cast<const char*>(xyz), sizeof(xyz));
        binary.append(reinterpret_cast<const char*>(&ns), sizeof(ns));
    }
    const shine::TimedPoints scan = shine::parse_pcd_scan(binary, "binary.pcd");
    ASSERT_EQ(scan.point_time_s.size(), 2u);
    EXPECT_NEAR(scan.point_time_s[1], 0.07, kExactS);
    EXPECT_EQ(scan.time_format.type, "U4");
    // No time field: no times.
    EXPECT_TRUE(shine::parse_pcd_scan(pcd_with_time("ring", "U", "2", {"1", "2"}), "p.pcd")
                    .point_time_s.empty());
}
