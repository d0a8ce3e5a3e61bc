// `shine simulate --cameras`: camera.yaml and one PNG of the calibration's size per scan, with the
// scan's stem, readable as the sequence's camera rig (io/camera_rig.hpp); the scans, poses and
// reference mesh are those of a run without --cameras byte for byte; without it no cameras/
// folder, and one left by an earlier run goes; with --route-km it is refused.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>

#include "cli_test_support.hpp"
#include "shine/io/camera_rig.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {

constexpr int kScans = 3;
constexpr int kSeed = 2;

fs::path test_dir() { return test_dir_of("cli_sim_cameras"); }

/// Simulates the 3-scan street into test_dir()/`name` with `extra` options.
fs::path simulate(const std::string& name, const std::string& extra) {
    const fs::path d = test_dir() / name;
    const CliResult r =
        run_shine("simulate -o '" + d.string() + "' --frames " + std::to_string(kScans) +
                      " --seed " + std::to_string(kSeed) + " --no-progress " + extra,
                  test_dir());
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return d;
}

std::string stem(int frame) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d", frame);
    return name;
}

/// Width and height from a PNG's IHDR chunk (bytes 16..23, big-endian).
std::pair<std::uint32_t, std::uint32_t> png_size(const fs::path& path) {
    const std::string bytes = read_text(path);
    EXPECT_GE(bytes.size(), 24u) << path;
    EXPECT_EQ(bytes.substr(1, 3), "PNG") << path;
    if (bytes.size() < 24) return {0, 0};
    auto be32 = [&](std::size_t at) {
        std::uint32_t v = 0;
        for (std::size_t i = 0; i < 4; ++i)
            v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
        return v;
    };
    return {be32(16), be32(20)};
}

}  // namespace

TEST(SimulateCamerasCli, WritesTheCalibrationAndOneImagePerScan) {
    const fs::path d = simulate("cameras", "--cameras");
    const fs::path front = d / "cameras" / "front";
    ASSERT_TRUE(fs::exists(front / "camera.yaml"));
    for (int k = 0; k < kScans; ++k) {
        ASSERT_TRUE(fs::exists(d / "velodyne" / (stem(k) + ".bin")));
        const fs::path png = front / (stem(k) + ".png");
        ASSERT_TRUE(fs::exists(png)) << png;
        const auto [width, height] = png_size(png);
        EXPECT_EQ(width, 640u);
        EXPECT_EQ(height, 240u);
    }
    EXPECT_FALSE(fs::exists(front / (stem(kScans) + ".png")));
    EXPECT_NE(read_text(d / "README.txt").find("cameras/front/"), std::string::npos);

    // The sequence's camera rig, as the colour fusion reads it.
    const auto rig = shine::find_camera_rig(d);
    ASSERT_TRUE(rig.has_value());
    ASSERT_EQ(rig->cameras.size(), 1u);
    const shine::RigCamera& camera = rig->cameras.front();
    EXPECT_EQ(camera.name, "front");
    EXPECT_EQ(camera.width, 640);
    EXPECT_EQ(camera.height, 240);
    EXPECT_EQ(camera.fx, 320.0);
    EXPECT_EQ(camera.cy, 119.5);
    // Looking along the LiDAR's +x, 0.27 m ahead of it and 0.08 m below.
    EXPECT_TRUE(camera.T_lidar_camera.linear().col(2).isApprox(Eigen::Vector3d::UnitX()));
    EXPECT_TRUE(camera.T_lidar_camera.translation().isApprox(Eigen::Vector3d(0.27, 0.0, -0.08)));
    EXPECT_EQ(rig->image_for_scan(0, d / "velodyne" / (stem(1) + ".bin")),
              front / (stem(1) + ".png"));
}

TEST(SimulateCamerasCli, OtherFilesAreTheSameWithAndWithoutCameras) {
    const fs::path with = simulate("with", "--cameras");
    const fs::path without = simulate("without", "");
    EXPECT_FALSE(fs::exists(without / "cameras"));
    for (const std::string file : {"poses.txt", "gt_mesh.ply", "simulation.json"}) {
        EXPECT_EQ(read_text(with / file), read_text(without / file)) << file;
    }
    for (int k = 0; k < kScans; ++k) {
        const fs::path scan = fs::path("velodyne") / (stem(k) + ".bin");
        EXPECT_EQ(read_text(with / scan), read_text(without / scan)) << scan;
    }
    // README.txt gains the cameras' lines only.
    const std::string readme = read_text(without / "README.txt");
    EXPECT_EQ(read_text(with / "README.txt").substr(0, readme.size()), readme);
}

TEST(SimulateCamerasCli, ARunWithoutCamerasRemovesAnEarlierRunsImages) {
    const fs::path d = simulate("rerun", "--cameras");
    ASSERT_TRUE(fs::exists(d / "cameras" / "front" / "camera.yaml"));
    const CliResult r =
        run_shine("simulate -o '" + d.string() + "' --frames 2 --seed 5 --no-progress", test_dir());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_FALSE(fs::exists(d / "cameras")) << r.output;
    EXPECT_NE(r.output.find("left by an earlier run with --cameras"), std::string::npos)
        << r.output;
}

TEST(SimulateCamerasCli, RefusedWithTheCityRoute) {
    const fs::path d = test_dir() / "route";
    const CliResult r = run_shine(
        "simulate -o '" + d.string() + "' --route-km 0.3 --cameras --no-progress", test_dir());
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("--cameras"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("--route-km"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(d / "cameras"));
}
