// scan_in_map_frame(): the map origin (first scan's position rounded to whole km, or
// map.origin_world_m) and the world-frame crop that tiles of a larger map use.
#include <gtest/gtest.h>

#include "shine/mapper/scan_in_map.hpp"

namespace shine {
namespace {

Scan scan_at(const Eigen::Vector3d& position_world_m) {
    Scan scan;
    for (int i = -10; i <= 10; ++i) {
        scan.points_sensor.emplace_back(static_cast<float>(i), 5.0f, 0.0f);  // x from -10 to 10 m
    }
    scan.T_world_sensor.translation() = position_world_m;
    scan.source = "line";
    return scan;
}

TEST(ScanInMap, FirstScanFixesTheOriginUnlessConfigured) {
    MapperConfig config;
    config.preprocess.voxel_downsample_m = 0.0;
    NeuralSdf sdf(config.octree, config.decoder);
    bool origin_set = false;
    PreprocessStats stats;
    const Eigen::Vector3d position(501234.0, 4999876.0, 10.0);
    ScanInMap s = scan_in_map_frame(scan_at(position), config, sdf, origin_set, stats);
    EXPECT_TRUE(origin_set);
    EXPECT_EQ(sdf.origin_world_m, Eigen::Vector3d(501000.0, 5000000.0, 0.0));
    EXPECT_TRUE(s.origin_map.isApprox(Eigen::Vector3f(234.0f, -124.0f, 10.0f)));
    EXPECT_EQ(stats.output, 21u);

    config.origin_world_m = {500000.0, 5000000.0, 0.0};
    NeuralSdf fixed(config.octree, config.decoder);
    origin_set = false;
    s = scan_in_map_frame(scan_at(position), config, fixed, origin_set, stats);
    EXPECT_EQ(fixed.origin_world_m, Eigen::Vector3d(500000.0, 5000000.0, 0.0));
    EXPECT_TRUE(s.origin_map.isApprox(Eigen::Vector3f(1234.0f, -124.0f, 10.0f)));
}

TEST(ScanInMap, WorldCropKeepsThePointsInsideTheHalfOpenBox) {
    MapperConfig config;
    config.preprocess.voxel_downsample_m = 0.0;
    config.preprocess.min_range_m = 0.1;
    const Eigen::Vector3d position(2000.0, 0.0, 0.0);
    // World x from 1997 (inclusive) to 2003 (exclusive): the points x = -3 .. 2 of the line.
    config.crop_world_m = {1997.0, -100.0, -100.0, 2003.0, 100.0, 100.0};
    NeuralSdf sdf(config.octree, config.decoder);
    bool origin_set = false;
    PreprocessStats stats;
    const ScanInMap s = scan_in_map_frame(scan_at(position), config, sdf, origin_set, stats);
    ASSERT_EQ(s.points_map.size(), 6u);
    for (const auto& p : s.points_map) {
        const double x_world = p.x() + sdf.origin_world_m.x();
        EXPECT_GE(x_world, 1997.0);
        EXPECT_LT(x_world, 2003.0);
    }
    EXPECT_EQ(stats.dropped_box, 15u);
    EXPECT_EQ(stats.output, 6u);
}

}  // namespace
}  // namespace shine
