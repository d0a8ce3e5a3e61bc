// The spherical LiDAR model on a real KITTI-360 scan (a Velodyne HDL-64E): its lasers leave from
// two heights above the sensor origin (0.12 and 0.21 m), which merged the upper rings when they
// were clustered by their elevation from the origin. Skipped when the shared data is absent.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "shine/render/lidar_model.hpp"

namespace shine {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

const fs::path kScan = fs::path(__FILE__).parent_path().parent_path().parent_path() / "shared" /
                       "data" / "kitti360_drive" / "velodyne" / "000000.bin";

// Measured on this scan: 63 of the 64 rings (two close rings of the lower block, seen mostly on
// the ground at one range, are not told apart), 2001 columns (0.18 deg), rings from 1.93 to
// -25.00 deg; per-laser fits of the stored rings give 1.94 to -25.00 deg.
constexpr int kMinRings = 60;
constexpr int kMaxRings = 64;
constexpr int kMinColumns = 1990, kMaxColumns = 2010;
constexpr double kTopDeg = 1.94, kBottomDeg = -25.0;
constexpr double kElevationToleranceDeg = 0.3;

std::vector<Eigen::Vector3f> read_kitti_bin(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::vector<Eigen::Vector3f> points;
    float xyzi[4];
    while (in.read(reinterpret_cast<char*>(xyzi), sizeof(xyzi))) {
        points.emplace_back(xyzi[0], xyzi[1], xyzi[2]);
    }
    return points;
}

TEST(RenderLidarModelReal, FindsTheRingsAndColumnsOfAKitti360Hdl64Scan) {
    if (!fs::exists(kScan)) GTEST_SKIP() << kScan << " is absent";
    const std::vector<Eigen::Vector3f> points = read_kitti_bin(kScan);
    ASSERT_GT(points.size(), 100000u);
    const SphericalLidarModel model = infer_spherical_lidar(points);
    EXPECT_GE(model.height(), kMinRings);
    EXPECT_LE(model.height(), kMaxRings);
    EXPECT_GE(model.width(), kMinColumns);
    EXPECT_LE(model.width(), kMaxColumns);
    EXPECT_NEAR(model.elevations_rad.front() / kDeg, kTopDeg, kElevationToleranceDeg);
    EXPECT_NEAR(model.elevations_rad.back() / kDeg, kBottomDeg, kElevationToleranceDeg);
    // The upper block's lasers sit about 0.2 m above the origin, the lower block's 0.12 m.
    EXPECT_NEAR(model.beam_heights_m.front(), 0.205, 0.02);
    // Most returns land in a pixel of their own.
    const PixelRays rays = scan_pixel_rays(model, points, 1.0, 150.0);
    std::size_t filled = 0;
    for (const float range_m : rays.measured_range_m) filled += !std::isnan(range_m);
    EXPECT_GT(double(filled), 0.75 * double(rays.measured_range_m.size()));
}

}  // namespace
}  // namespace shine
