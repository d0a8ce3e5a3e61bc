// The held-out yardstick (eval/heldout_ranges.hpp) on analytic surfaces: a plane and a closed
// box, with rays whose measured ranges are exact, offset by known amounts, or pointing at nothing.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/eval/heldout_ranges.hpp"
#include "shine/geometry/ray_caster.hpp"
#include "shine/geometry/triangle_mesh.hpp"

using namespace shine;

namespace {

constexpr double kExactM = 1e-5;  // float points, double ray casting: 10 um

/// The square [-half, half]^2 of the plane z = 0, two triangles.
TriangleMesh ground_square(float half) {
    TriangleMesh mesh;
    mesh.vertices = {
        {-half, -half, 0.0f}, {half, -half, 0.0f}, {half, half, 0.0f}, {-half, half, 0.0f}};
    mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
    return mesh;
}

/// The closed box [-h, h]^3, twelve triangles.
TriangleMesh box(float h) {
    TriangleMesh mesh;
    for (int i = 0; i < 8; ++i) {
        mesh.vertices.emplace_back(i & 1 ? h : -h, i & 2 ? h : -h, i & 4 ? h : -h);
    }
    mesh.triangles = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                      {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
    return mesh;
}

Eigen::Vector3f unit(double azimuth, double elevation) {
    return Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                           std::cos(elevation) * std::sin(azimuth), std::sin(elevation))
        .cast<float>();
}

}  // namespace

TEST(HeldoutRanges, PointsOnAPlaneScoreZeroErrorAndSkyRaysAreMisses) {
    const TriangleMesh mesh = ground_square(100.0f);
    const RayCaster caster(mesh);
    // Sensor 2 m above the plane, yawed: 200 rays down onto the plane at their true ranges, 100
    // rays upward with a made-up range (a return the map has no surface for).
    Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
    T_world_sensor.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T_world_sensor.translation() = Eigen::Vector3d(3.0, -4.0, 2.0);
    std::vector<Eigen::Vector3f> points_sensor;
    for (int i = 0; i < 200; ++i) {
        const Eigen::Vector3f d = unit(0.0314 * i, -0.2 - 0.005 * i);
        points_sensor.push_back(d * static_cast<float>(2.0 / -d.z()));
    }
    for (int i = 0; i < 100; ++i) points_sensor.push_back(unit(0.06 * i, 0.3) * 10.0f);
    HeldoutConfig config;
    std::vector<float> errors;
    const RangeErrorStats stats = score_scan_ranges(caster, Eigen::Vector3d::Zero(), points_sensor,
                                                    T_world_sensor, config, &errors);
    EXPECT_EQ(stats.rays, 300u);
    EXPECT_EQ(stats.hits, 200u);
    EXPECT_EQ(stats.within, 200u);
    EXPECT_DOUBLE_EQ(stats.hit_ratio(), 200.0 / 300.0);
    EXPECT_DOUBLE_EQ(stats.within_ratio(), 200.0 / 300.0);  // misses fail
    EXPECT_LT(stats.median_abs_error_m, kExactM);
    EXPECT_LT(stats.mean_abs_error_m, kExactM);
    ASSERT_EQ(errors.size(), 200u);
}

TEST(HeldoutRanges, KnownRangeOffsetsGiveTheirErrorsInsideABox) {
    // The sensor at the centre of a 10 m box: every ray hits. A third of the rays measure 5 cm
    // too far, a third 20 cm too short (the surface lies behind the return), a third exactly.
    const TriangleMesh mesh = box(5.0f);
    const RayCaster caster(mesh);
    std::vector<Eigen::Vector3f> points_sensor;
    std::vector<double> offsets_m;
    for (int i = 0; i < 300; ++i) {
        const Eigen::Vector3f d = unit(0.021 * i, -1.0 + 0.0066 * i);
        const double true_range_m =
            caster.cast(Eigen::Vector3d::Zero(), d.cast<double>()).distance_m;
        const double offset_m = i % 3 == 0 ? 0.05 : (i % 3 == 1 ? -0.20 : 0.0);
        offsets_m.push_back(std::abs(offset_m));
        points_sensor.push_back(d * static_cast<float>(true_range_m + offset_m));
    }
    const RangeErrorStats stats = score_scan_ranges(caster, Eigen::Vector3d::Zero(), points_sensor,
                                                    Eigen::Isometry3d::Identity(), HeldoutConfig{});
    EXPECT_EQ(stats.rays, 300u);
    EXPECT_EQ(stats.hits, 300u);
    EXPECT_EQ(stats.within, 200u);  // exact and 5 cm; not the 20 cm ones
    EXPECT_NEAR(stats.median_abs_error_m, 0.05, kExactM);
    EXPECT_NEAR(stats.mean_abs_error_m, (0.05 + 0.20) / 3.0, kExactM);
}

TEST(HeldoutRanges, MapOriginShiftsTheSensorAndRangeLimitsDropRays) {
    // The mesh is stored relative to a far-away origin (UTM-like); the sensor pose is in world
    // coordinates. Rays measured closer than min_range_m are not scored at all.
    TriangleMesh mesh = ground_square(50.0f);
    mesh.origin_world_m = Eigen::Vector3d(500000.0, 5000000.0, 0.0);
    const RayCaster caster(mesh);
    Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
    T_world_sensor.translation() = mesh.origin_world_m + Eigen::Vector3d(1.0, 2.0, 1.0);
    const std::vector<Eigen::Vector3f> points_sensor = {
        {0.0f, 0.0f, -1.0f},  // 1 m: closer than min_range_m
        {3.0f, 0.0f, -1.0f},  // on the plane at sqrt(10) m
        {0.0f, 4.0f, -1.0f}};
    HeldoutConfig config;
    config.min_range_m = 1.5;
    const RangeErrorStats stats =
        score_scan_ranges(caster, mesh.origin_world_m, points_sensor, T_world_sensor, config);
    EXPECT_EQ(stats.rays, 2u);
    EXPECT_EQ(stats.hits, 2u);
    EXPECT_LT(stats.mean_abs_error_m, kExactM);
}

TEST(HeldoutRanges, FrameListsAndHoldoutFrames) {
    EXPECT_EQ(holdout_frames(10, 3), (std::vector<std::size_t>{2, 5, 8}));
    EXPECT_EQ(holdout_frames(10, 2), (std::vector<std::size_t>{1, 3, 5, 7, 9}));
    EXPECT_TRUE(holdout_frames(1, 2).empty());
    EXPECT_THROW(holdout_frames(10, 1), ConfigError);
    EXPECT_EQ(parse_frame_list("2,5,8", 10), (std::vector<std::size_t>{2, 5, 8}));
    EXPECT_EQ(parse_frame_list("2:8:3", 10), (std::vector<std::size_t>{2, 5, 8}));
    EXPECT_EQ(parse_frame_list("7,1:3,2", 10), (std::vector<std::size_t>{1, 2, 3, 7}));
    for (const char* bad : {"", "1,,2", "a", "10", "3:1", "1:4:0", "1:2:3:4", "-1"}) {
        EXPECT_THROW(parse_frame_list(bad, 10), ConfigError) << bad;
    }
}
