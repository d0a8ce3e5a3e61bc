// scan_in_map_frame(): the map origin (first scan's position rounded to whole km, or
// map.origin_world_m) and the world-frame crop that tiles of a larger map use.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <string>

#include "shine/core/error.hpp"
#include "shine/geometry/map_frame.hpp"
#include "shine/mapper/scan_in_map.hpp"
#include "shine/mapper/sequence_deskew.hpp"
#include "shine/odometry/scan_deskew.hpp"

namespace shine {
namespace {

constexpr int kRandomPoints = 20000;

/// kRandomPoints random points in a 6 m cube around a sensor 1 km from the world origin.
Scan random_scan(unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> coordinate(-3.0f, 3.0f);
    Scan scan;
    scan.source = "random";
    scan.T_world_sensor.translation() = Eigen::Vector3d(1000.3, -20.7, 1.1);
    for (int i = 0; i < kRandomPoints; ++i) {
        scan.points_sensor.emplace_back(coordinate(rng), coordinate(rng), coordinate(rng));
    }
    return scan;
}

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

TEST(ScanInMap, EachKeptPointKeepsTheOriginItWasMeasuredFrom) {
    // A deskewed scan: point i was measured from (0.01 i, 0, 0) in its sensor frame. Thinning
    // and the world crop keep some points; each kept one carries its own origin into the map
    // frame, and a scan without origins carries none.
    MapperConfig config;
    config.preprocess.voxel_downsample_m = 2.0;  // one point of the line per 2 m voxel
    config.preprocess.min_range_m = 0.1;
    config.crop_world_m = {1995.0, -100.0, -100.0, 2007.0, 100.0, 100.0};
    Scan scan = scan_at(Eigen::Vector3d(2000.0, 0.0, 0.0));
    for (std::size_t i = 0; i < scan.points_sensor.size(); ++i) {
        scan.point_origin_sensor.emplace_back(0.01f * static_cast<float>(i), 0.0f, 0.0f);
    }
    NeuralSdf sdf(config.octree, config.decoder);
    bool origin_set = false;
    PreprocessStats stats;
    const ScanInMap s = scan_in_map_frame(scan, config, sdf, origin_set, stats);
    ASSERT_GT(s.points_map.size(), 2u);
    ASSERT_LT(s.points_map.size(), scan.points_sensor.size());
    ASSERT_EQ(s.point_origins_map.size(), s.points_map.size());
    for (std::size_t k = 0; k < s.points_map.size(); ++k) {
        // The line's point i lies at sensor x = i - 10.
        const float x_sensor = s.points_map[k].x() - s.origin_map.x();
        const int i = static_cast<int>(std::lround(x_sensor)) + 10;
        EXPECT_FLOAT_EQ(s.point_origins_map[k].x() - s.origin_map.x(), 0.01f * i) << k;
        EXPECT_FLOAT_EQ(s.point_origins_map[k].y(), s.origin_map.y());
    }
    scan.point_origin_sensor.clear();
    EXPECT_TRUE(scan_in_map_frame(scan, config, sdf, origin_set, stats).point_origins_map.empty());
}

TEST(ScanInMap, EachKeptPointKeepsItsIntensityThroughThinningCropAndRunDrops) {
    // 20 000 random points, point i with intensity i (NaN for every 97th: kept with its point),
    // thinned or grouped in 0.5 m voxels, cropped in the world: every kept point carries the
    // intensity of the input point it is. A scan without intensity carries none.
    Scan scan = random_scan(11);
    for (int i = 0; i < kRandomPoints; ++i) {
        scan.intensity.push_back(i % 97 == 5 ? NAN : static_cast<float>(i));
    }
    MapperConfig config;
    config.preprocess.min_range_m = 0.5;
    config.preprocess.voxel_downsample_m = 0.5;
    config.preprocess.voxel_points = VoxelPoints::kAll;
    config.crop_world_m = {999.5, -30.0, -10.0, 1001.5, -18.0, 10.0};  // x from -0.8 m to 1.2 m
    NeuralSdf sdf(config.octree, config.decoder);
    bool origin_set = false;
    PreprocessStats stats;
    ScanInMap grouped = scan_in_map_frame(scan, config, sdf, origin_set, stats, true);
    const ScanInMap thinned = scan_in_map_frame(scan, config, sdf, origin_set, stats, false);
    const Eigen::Isometry3d T_map_sensor = map_from_sensor(scan.T_world_sensor, sdf.origin_world_m);
    // Point k of `s` is the input point its intensity names (NaN: one of the every-97th).
    const auto expect_own_intensity = [&](const ScanInMap& s, const char* what) {
        ASSERT_EQ(s.point_intensity.size(), s.points_map.size()) << what;
        std::size_t nan = 0;
        for (std::size_t k = 0; k < s.points_map.size(); ++k) {
            const float value = s.point_intensity[k];
            if (std::isnan(value)) {
                ++nan;
                continue;
            }
            const auto i = static_cast<std::size_t>(value);
            ASSERT_LT(i, scan.points_sensor.size()) << what;
            ASSERT_EQ(s.points_map[k],
                      points_in_map_frame({scan.points_sensor[i]}, T_map_sensor).front())
                << what << " point " << k << " intensity " << value;
        }
        EXPECT_GT(nan, 0u) << what;  // NaN intensities keep their points
    };
    ASSERT_GT(thinned.points_map.size(), 100u);
    ASSERT_LT(grouped.points_map.size(), 20000u / 2);  // the crop removed two thirds
    expect_own_intensity(thinned, "thinned");
    expect_own_intensity(grouped, "grouped");
    // The crop cuts runs, so the leads differ from the thinned scan; each still has its own.
    expect_own_intensity(voxel_leads(grouped), "leads");
    std::vector<std::uint8_t> drop(grouped.voxel_begin.size());
    for (std::size_t r = 1; r < drop.size(); r += 2) drop[r] = 1;
    drop_voxel_runs(grouped, drop);
    expect_own_intensity(grouped, "grouped after dropping every second run");
    expect_own_intensity(voxel_leads(grouped), "leads after dropping");
    scan.intensity.resize(10);  // not one per point: an error naming the scan
    try {
        scan_in_map_frame(scan, config, sdf, origin_set, stats);
        ADD_FAILURE() << "expected DataError";
    } catch (const DataError& e) {
        EXPECT_NE(std::string(e.what()).find("'random': 20000 points but 10 intensities"),
                  std::string::npos)
            << e.what();
    }
    scan.intensity.clear();
    EXPECT_TRUE(scan_in_map_frame(scan, config, sdf, origin_set, stats).point_intensity.empty());
}

TEST(ScanInMap, DeskewingGivesEachPointTheSensorPositionAtItsTime) {
    // A sweep of 0.1 s during which the sensor moved 1 m along x and turned 2 degrees: each
    // point's origin is the sensor's position at the point's time, in the scan's frame.
    Scan scan = scan_at(Eigen::Vector3d::Zero());
    for (std::size_t i = 0; i < scan.points_sensor.size(); ++i) {
        scan.point_time_s.push_back(-0.1 + 0.005 * static_cast<double>(i));
    }
    Eigen::Isometry3d T_prev_cur = Eigen::Isometry3d::Identity();
    T_prev_cur.translate(Eigen::Vector3d(1.0, 0.0, 0.0));
    T_prev_cur.rotate(Eigen::AngleAxisd(2.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()));
    DeskewStats stats;
    deskew_in_place(scan, T_prev_cur, 0.1, stats);
    ASSERT_EQ(scan.point_origin_sensor.size(), scan.points_sensor.size());
    for (std::size_t i = 0; i < scan.points_sensor.size(); ++i) {
        const Eigen::Vector3d expected =
            sensor_pose_at(T_prev_cur, 0.1, scan.point_time_s[i]).translation();
        EXPECT_LT((scan.point_origin_sensor[i].cast<double>() - expected).norm(), 1e-6) << i;
    }
    EXPECT_NEAR(scan.point_origin_sensor.front().x(), -1.0, 1e-3);  // a sweep earlier
    EXPECT_NEAR(scan.point_origin_sensor.back().x(), 0.0, 1e-3);    // at the scan's time
}

TEST(ScanInMap, VoxelLeadsAreTheThinnedScanAndRunsDropWithTheirLeads) {
    // 20 000 random points, each with its own origin, in 0.5 m voxels: the leads of the grouped
    // scan are the thinned scan point for point; dropping runs by flag keeps the other runs whole
    // and in order, with their origins.
    Scan scan = random_scan(7);
    for (int i = 0; i < kRandomPoints; ++i) {
        scan.point_origin_sensor.emplace_back(0.001f * static_cast<float>(i), 0.0f, 0.0f);
    }
    MapperConfig config;
    config.preprocess.min_range_m = 0.5;
    config.preprocess.voxel_downsample_m = 0.5;
    config.preprocess.voxel_points = VoxelPoints::kAll;
    NeuralSdf sdf(config.octree, config.decoder);
    bool origin_set = false;
    PreprocessStats stats;
    const ScanInMap thinned = scan_in_map_frame(scan, config, sdf, origin_set, stats, false);
    ScanInMap grouped = scan_in_map_frame(scan, config, sdf, origin_set, stats, true);
    ASSERT_EQ(grouped.voxel_begin.size(), thinned.points_map.size());
    ASSERT_GT(grouped.points_map.size(), 3 * thinned.points_map.size());
    const ScanInMap leads = voxel_leads(grouped);
    EXPECT_TRUE(leads.voxel_begin.empty());
    EXPECT_EQ(leads.origin_map, thinned.origin_map);
    EXPECT_EQ(leads.points_map, thinned.points_map);
    EXPECT_EQ(leads.point_origins_map, thinned.point_origins_map);

    // Drop every third run.
    std::vector<std::uint8_t> drop(grouped.voxel_begin.size());
    for (std::size_t r = 0; r < drop.size(); r += 3) drop[r] = 1;
    std::vector<Eigen::Vector3f> expected_points, expected_origins;
    std::vector<std::uint32_t> expected_begin;
    for (std::size_t r = 0; r < drop.size(); ++r) {
        if (drop[r]) continue;
        const std::size_t end =
            r + 1 < drop.size() ? grouped.voxel_begin[r + 1] : grouped.points_map.size();
        expected_begin.push_back(static_cast<std::uint32_t>(expected_points.size()));
        for (std::size_t i = grouped.voxel_begin[r]; i < end; ++i) {
            expected_points.push_back(grouped.points_map[i]);
            expected_origins.push_back(grouped.point_origins_map[i]);
        }
    }
    const std::size_t before = grouped.points_map.size();
    EXPECT_EQ(drop_voxel_runs(grouped, drop), before - expected_points.size());
    EXPECT_EQ(grouped.points_map, expected_points);
    EXPECT_EQ(grouped.point_origins_map, expected_origins);
    EXPECT_EQ(grouped.voxel_begin, expected_begin);
    // The leads that are left are the thinned points whose runs were kept.
    const ScanInMap left = voxel_leads(grouped);
    std::size_t k = 0;
    for (std::size_t r = 0; r < drop.size(); ++r) {
        if (drop[r]) continue;
        ASSERT_LT(k, left.points_map.size());
        EXPECT_EQ(left.points_map[k], thinned.points_map[r]);
        EXPECT_EQ(left.point_origins_map[k], thinned.point_origins_map[r]);
        ++k;
    }
    EXPECT_EQ(k, left.points_map.size());
    EXPECT_THROW(drop_voxel_runs(grouped, drop), std::invalid_argument);  // a flag per old run
}

}  // namespace
}  // namespace shine
