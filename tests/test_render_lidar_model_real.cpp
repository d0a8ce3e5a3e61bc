// The spherical LiDAR model on a real KITTI-360 scan (a Velodyne HDL-64E): its lasers leave from
// two heights above the sensor origin (0.12 and 0.21 m), which merged the upper rings when they
// were clustered by their elevation from the origin. Skipped when the shared data is absent.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "shine/render/lidar_model.hpp"

namespace shine {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;

const fs::path kDrive = fs::path(__FILE__).parent_path().parent_path().parent_path() / "shared" /
                        "data" / "kitti360_drive" / "velodyne";
const fs::path kScan = kDrive / "000000.bin";

// Measured on this scan: all 64 rings, 2001 columns (0.18 deg), rings from 1.95 to -25.05 deg;
// per-laser fits of the stored rings give 1.94 to -25.00 deg.
constexpr int kMinRings = 63;
constexpr int kMaxRings = 64;
constexpr int kMinColumns = 1990, kMaxColumns = 2010;
constexpr double kTopDeg = 1.94, kBottomDeg = -25.0;
constexpr double kElevationToleranceDeg = 0.3;

// Measured over all 25 scans of the drive: 64 rings and 2001-2002 columns on each; top ring
// 1.93-1.96 deg; bottom ring -24.52 to -25.05 deg (it mostly hits the ground at one range, where
// its elevation and beam height trade off). Before the spin axis was chosen by the points its
// rings hold in focus, scans 23 and 24 gave 23 and 18 rings, and others 59-63.
constexpr int kDriveMinRings = 63;
constexpr int kDriveMinColumns = 2000, kDriveMaxColumns = 2003;
constexpr double kDriveTopDeg = 1.95, kDriveTopToleranceDeg = 0.1;
constexpr double kDriveBottomDeg = -24.8, kDriveBottomToleranceDeg = 0.4;

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

// Every third scan and scan 23 (where the axis search settles 0.09 deg off the sensor's z and
// merged the upper block): about 2-3 s of inference a scan.
TEST(RenderLidarModelReal, FindsAllRingsOnASpreadOfKitti360Scans) {
    if (!fs::exists(kDrive)) GTEST_SKIP() << kDrive << " is absent";
    for (const int frame : {0, 3, 6, 9, 12, 15, 18, 21, 23, 24}) {
        char name[16];
        std::snprintf(name, sizeof(name), "%06d.bin", frame);
        SCOPED_TRACE(name);
        const std::vector<Eigen::Vector3f> points = read_kitti_bin(kDrive / name);
        ASSERT_GT(points.size(), 100000u);
        const SphericalLidarModel model = infer_spherical_lidar(points);
        EXPECT_GE(model.height(), kDriveMinRings);
        EXPECT_LE(model.height(), kMaxRings);
        EXPECT_GE(model.width(), kDriveMinColumns);
        EXPECT_LE(model.width(), kDriveMaxColumns);
        EXPECT_NEAR(model.elevations_rad.front() / kDeg, kDriveTopDeg, kDriveTopToleranceDeg);
        EXPECT_NEAR(model.elevations_rad.back() / kDeg, kDriveBottomDeg, kDriveBottomToleranceDeg);
    }
}

}  // namespace
}  // namespace shine
