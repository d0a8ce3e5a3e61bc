// End to end: `shine render` on a simulated street (needs the `shine` executable built). The
// street's own reference mesh stands in for a map, so the rendered range error measures the
// renderer and the simulator's range noise, not a mapper.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include "cli_test_support.hpp"
#include "shine/render/exr_image.hpp"

namespace shine {
namespace {

using cli_test::CliResult;
using cli_test::run_shine;
namespace fs = std::filesystem;

class RenderCli : public ::testing::Test {
  protected:
    static void SetUpTestSuite() {
        street_ = fs::path(SHINE_TEST_TMP_DIR) / "render_cli" / "street";
        if (!fs::exists(street_ / "gt_mesh.ply")) {
            fs::remove_all(street_);
            const std::string command = "'" + std::string(SHINE_CLI_PATH) + "' simulate -o '" +
                                        street_.string() +
                                        "' --frames 3 --seed 5 --no-progress > /dev/null 2>&1";
            ASSERT_EQ(std::system(command.c_str()), 0);
        }
    }
    void SetUp() override {
        if (!fs::exists(SHINE_CLI_PATH)) GTEST_SKIP() << "build the shine target first";
        dir_ = cli_test::test_dir_of("render_cli");
        fs::remove_all(dir_ / "out");
    }
    std::string render(const std::string& input, const std::string& args) const {
        return "render '" + input + "' -o '" + (dir_ / "out").string() + "' " + args;
    }
    static fs::path street_;
    fs::path dir_;
};
fs::path RenderCli::street_;

TEST_F(RenderCli, RendersASimulatedScanInItsOwn64RingProjection) {
    const CliResult r = run_shine(
        render((street_ / "gt_mesh.ply").string(), "--scans '" + street_.string() + "' --frame 1"),
        dir_);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    // The simulator's LiDAR has 64 beams.
    EXPECT_NE(r.output.find(": 64 rings"), std::string::npos) << r.output;
    for (const char* name : {"frame_000001.exr", "frame_000001_range.png",
                             "frame_000001_normal.png", "frame_000001_error.png"}) {
        EXPECT_TRUE(fs::is_regular_file(dir_ / "out" / name)) << name;
    }
    const ExrImage image = read_exr(dir_ / "out" / "frame_000001.exr");
    EXPECT_EQ(image.height(), 64);
    for (const char* channel :
         {"range.V", "normal.X", "normal.Y", "normal.Z", "measured.V", "error.V"}) {
        EXPECT_TRUE(image.has_channel(channel)) << channel;
    }
    // Against the mesh the scan was simulated from, every return has a surface at its measured
    // range (measured here: 100.00 % hit, median |error| 0.00 cm, frame 1 of seed 5).
    constexpr double kWithinM = 0.01;  // 1 cm
    std::size_t returns = 0, hits = 0, within = 0;
    const auto& error = image.channel("error.V");
    const auto& measured = image.channel("measured.V");
    for (std::size_t i = 0; i < error.size(); ++i) {
        if (std::isnan(measured[i])) continue;
        ++returns;
        if (std::isnan(error[i])) continue;
        ++hits;
        within += std::abs(error[i]) <= kWithinM;
    }
    ASSERT_GT(returns, 10000u);
    EXPECT_GT(double(hits) / returns, 0.999);
    EXPECT_GT(double(within) / returns, 0.99);
}

TEST_F(RenderCli, PinholeCameraGivesTheRequestedSize) {
    const CliResult r = run_shine(
        render((street_ / "gt_mesh.ply").string(),
               "--scans '" + street_.string() + "' --frame 0 --camera 100,100,80,60,160,120"),
        dir_);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const ExrImage image = read_exr(dir_ / "out" / "frame_000000.exr");
    EXPECT_EQ(image.width(), 160);
    EXPECT_EQ(image.height(), 120);
    EXPECT_FALSE(image.has_channel("error.V"));
    EXPECT_FALSE(fs::exists(dir_ / "out" / "frame_000000_error.png"));
}

/// Share of pixels whose ray meets the map (a finite predicted range).
double surface_share(const ExrImage& image) {
    const auto& range = image.channel("range.V");
    const auto hits =
        std::count_if(range.begin(), range.end(), [](float r) { return !std::isnan(r); });
    return static_cast<double>(hits) / static_cast<double>(range.size());
}

TEST_F(RenderCli, PinholeCameraLooksForwardByDefault) {
    // The obvious first try, a camera at a LiDAR pose, sees the street ahead (measured: 85.4 % of
    // the pixels meet the street's mesh, the rest is sky); aimed along the LiDAR's z, as the
    // camera used to be, it sees only sky.
    constexpr double kMinShare = 0.7;
    const std::string camera =
        "--scans '" + street_.string() + "' --frame 0 --camera 100,100,80,60,160,120";
    CliResult r = run_shine(render((street_ / "gt_mesh.ply").string(), camera), dir_);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_GT(surface_share(read_exr(dir_ / "out" / "frame_000000.exr")), kMinShare) << r.output;
    fs::remove_all(dir_ / "out");
    r = run_shine(
        render((street_ / "gt_mesh.ply").string(), camera + " --camera-rotation 1,0,0,0,1,0,0,0,1"),
        dir_);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_EQ(surface_share(read_exr(dir_ / "out" / "frame_000000.exr")), 0.0) << r.output;
}

TEST_F(RenderCli, PinholeCameraLooksAtAWorldPoint) {
    // The principal point (80, 60) of a camera aimed at the road 10 m ahead of frame 0's LiDAR
    // (the road is z = 0) meets the road at that point.
    constexpr double kToleranceM = 0.01;
    std::ifstream poses(street_ / "poses.txt");
    double T[12];
    for (double& x : T) ASSERT_TRUE(poses >> x);
    const Eigen::Vector3d sensor(T[3], T[7], T[11]);
    const Eigen::Vector3d target = sensor + Eigen::Vector3d(10.0, 0.0, -sensor.z());
    std::ostringstream look_at;
    look_at.precision(17);
    look_at << target.x() << "," << target.y() << "," << target.z();
    const CliResult r = run_shine(
        render((street_ / "gt_mesh.ply").string(),
               "--scans '" + street_.string() +
                   "' --frame 0 --camera 100,100,80,60,160,120 --camera-look-at " + look_at.str()),
        dir_);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const ExrImage image = read_exr(dir_ / "out" / "frame_000000.exr");
    EXPECT_NEAR(image.channel("range.V")[60 * 160 + 80], (target - sensor).norm(), kToleranceM);
    // Aiming without a camera, or both ways at once, is an error.
    EXPECT_NE(
        run_shine(render((street_ / "gt_mesh.ply").string(),
                         "--scans '" + street_.string() + "' --frame 0 --camera-look-at 1,2,3"),
                  dir_)
            .exit_code,
        0);
    EXPECT_NE(
        run_shine(render((street_ / "gt_mesh.ply").string(),
                         "--scans '" + street_.string() +
                             "' --frame 0 --camera 100,100,80,60,160,120 --camera-look-at 1,2,3 "
                             "--camera-rotation 0,0,1,-1,0,0,0,-1,0"),
                  dir_)
            .exit_code,
        0);
}

TEST_F(RenderCli, BadInputEndsWithAClearMessageAndNoOutput) {
    const std::string mesh = (street_ / "gt_mesh.ply").string();
    // A frame out of range.
    CliResult r = run_shine(render(mesh, "--scans '" + street_.string() + "' --frame 3"), dir_);
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("--frame 3 is outside the sequence"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir_ / "out"));
    // A pose file shorter than the scans.
    const fs::path short_seq = dir_ / "short";
    fs::remove_all(short_seq);
    fs::create_directories(short_seq);
    fs::copy(street_ / "velodyne", short_seq / "velodyne");
    {
        std::ifstream in(street_ / "poses.txt");
        std::ofstream out(short_seq / "poses.txt");
        std::string line;
        std::getline(in, line);
        out << line << "\n";
    }
    r = run_shine(render(mesh, "--scans '" + short_seq.string() + "' --frame 0"), dir_);
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("poses.txt"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir_ / "out"));
    // A mesh file that is not one.
    const fs::path not_mesh = dir_ / "not_a_mesh.ply";
    std::ofstream(not_mesh) << "this is not a PLY file\n";
    r = run_shine(render(not_mesh.string(), "--scans '" + street_.string() + "' --frame 0"), dir_);
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("not_a_mesh.ply"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir_ / "out"));
    // A map file that is not one (the slice needs map.vdb).
    const fs::path fake_map_dir = dir_ / "fake_map";
    fs::create_directories(fake_map_dir);
    fs::copy_file(mesh, fake_map_dir / "mesh.ply", fs::copy_options::overwrite_existing);
    std::ofstream(fake_map_dir / "map.vdb") << "not a vdb";
    r = run_shine(
        render(fake_map_dir.string(), "--scans '" + street_.string() + "' --frame 0 --slice z=1.5"),
        dir_);
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("map.vdb"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir_ / "out"));
}

}  // namespace
}  // namespace shine
