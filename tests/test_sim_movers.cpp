// Movers in the simulator: a ray's time decides where a mover is; scans are deterministic; a
// scene without movers gives the static scans.
#include <gtest/gtest.h>

#include <cmath>

#include "shine/geometry/ray_caster.hpp"
#include "shine/sim/lidar_simulator.hpp"
#include "shine/sim/mesh_primitives.hpp"
#include "shine/sim/moving_scene.hpp"
#include "shine/sim/street_movers.hpp"

namespace shine::sim {
namespace {

constexpr double kTolM = 1e-9;  // exact ray/box geometry

/// A wall 1 m thick with its face at x = 20, 40 m wide and 10 m high.
TriangleMesh wall() { return make_box_mesh({20.0f, -20.0f, -1.0f}, {21.0f, 20.0f, 9.0f}); }

/// A car that waits at x = 10 (across the ray along +x at z = 0.75) until t = 1 s, then drives
/// off along +y, 10 m per second.
MoverTracks car_leaving() {
    MoverTracks tracks;
    MoverTrack car;
    car.kind = MoverKind::kCar;
    car.waypoints = {
        {0.0, {10.0, 0.0, 0.0}, 0.0}, {1.0, {10.0, 0.0, 0.0}, 0.0}, {6.0, {10.0, 50.0, 0.0}, 0.0}};
    tracks.movers = {car};
    return tracks;
}

TEST(MovingScene, TheRayTimeDecidesWhereTheMoverIs) {
    const TriangleMesh static_mesh = wall();
    const RayCaster caster(static_mesh);
    const MovingScene scene(caster, car_leaving());
    const Eigen::Vector3d origin(0.0, 0.0, 0.75);
    const Eigen::Vector3d ahead = Eigen::Vector3d::UnitX();
    const RayHit at_t0 = scene.cast(origin, ahead, 0.0, 100.0, 0.5);
    ASSERT_TRUE(at_t0.hit());
    EXPECT_NEAR(at_t0.distance_m, 10.0 - 2.25, kTolM);  // the car's rear face
    EXPECT_EQ(static_cast<std::size_t>(at_t0.triangle_id), scene.num_static_triangles());
    const RayHit at_t1 = scene.cast(origin, ahead, 0.0, 100.0, 3.0);
    ASSERT_TRUE(at_t1.hit());
    EXPECT_NEAR(at_t1.distance_m, 20.0, kTolM);  // the wall behind
    EXPECT_LT(static_cast<std::size_t>(at_t1.triangle_id), scene.num_static_triangles());
    // Half way out at t = 1.05 s (0.5 m along +y): a ray at y = -0.5 just misses the car...
    EXPECT_NEAR(scene.cast({0.0, -0.45, 0.75}, ahead, 0.0, 100.0, 1.05).distance_m, 20.0, kTolM);
    // ... and one at y = -0.35 still hits it.
    EXPECT_NEAR(scene.cast({0.0, -0.35, 0.75}, ahead, 0.0, 100.0, 1.05).distance_m, 7.75, kTolM);
}

TEST(MovingScene, EachRayOfAScanSeesItsOwnTime) {
    const TriangleMesh static_mesh = wall();
    const RayCaster caster(static_mesh);
    // One beam, level, 4 azimuth steps (+x, +y, -x, -y); the sweep lasts 2 s, so the ray along +x
    // is cast at t0 and the others later.
    LidarConfig lidar;
    lidar.num_beams = 1;
    lidar.elevation_max_deg = lidar.elevation_min_deg = 0.0;
    lidar.azimuth_steps = 4;
    MoverTracks tracks = car_leaving();
    tracks.sweep_s = 2.0;
    const MovingScene scene(caster, tracks);
    const Eigen::Isometry3d pose(Eigen::Translation3d(0.0, 0.0, 0.75));
    const LidarScan early = simulate_scan(scene, lidar, pose, 7, 0.0);
    ASSERT_EQ(early.points_sensor.size(), 1u);  // only +x hits something: the car at t = 0
    EXPECT_NEAR(early.points_sensor[0].x(), 7.75, 1e-5);
    const LidarScan late = simulate_scan(scene, lidar, pose, 7, 2.0);
    ASSERT_EQ(late.points_sensor.size(), 1u);
    EXPECT_NEAR(late.points_sensor[0].x(), 20.0, 1e-5);
}

TEST(MovingScene, AMoverIsThereOnlyBetweenItsFirstAndLastWaypoint) {
    const TriangleMesh static_mesh = wall();
    const RayCaster caster(static_mesh);
    MoverTracks tracks;
    MoverTrack car;  // stands across the ray along +x from t = 1 to t = 2 s
    car.waypoints = {{1.0, {10.0, 0.0, 0.0}, 0.0}, {2.0, {10.0, 0.0, 0.0}, 0.0}};
    tracks.movers = {car};
    const MovingScene scene(caster, tracks);
    const Eigen::Vector3d origin(0.0, 0.0, 0.75);
    const Eigen::Vector3d ahead = Eigen::Vector3d::UnitX();
    EXPECT_NEAR(scene.cast(origin, ahead, 0.0, 100.0, 0.99).distance_m, 20.0, kTolM);
    EXPECT_NEAR(scene.cast(origin, ahead, 0.0, 100.0, 1.0).distance_m, 7.75, kTolM);
    EXPECT_NEAR(scene.cast(origin, ahead, 0.0, 100.0, 2.0).distance_m, 7.75, kTolM);
    EXPECT_NEAR(scene.cast(origin, ahead, 0.0, 100.0, 2.01).distance_m, 20.0, kTolM);
    // A scan's selection holds the movers present during its sweep and within its range only.
    EXPECT_EQ(scene.select(origin, 80.0, 0.0, 0.9).movers().size(), 0u);
    EXPECT_EQ(scene.select(origin, 80.0, 0.95, 1.05).movers().size(), 1u);
    EXPECT_EQ(scene.select(origin, 80.0, 2.05, 3.0).movers().size(), 0u);
    EXPECT_EQ(scene.select({200.0, 0.0, 0.75}, 80.0, 1.0, 2.0).movers().size(), 0u);
    // A path that passes by between its waypoints is within range.
    MoverTracks passing;
    MoverTrack through = car;
    through.waypoints = {{0.0, {-500.0, 0.0, 0.0}, 0.0}, {10.0, {500.0, 0.0, 0.0}, 0.0}};
    passing.movers = {through};
    const MovingScene passing_scene(caster, passing);
    EXPECT_EQ(passing_scene.select(origin, 80.0, 0.0, 10.0).movers().size(), 1u);
    EXPECT_EQ(passing_scene.select(origin, 80.0, 0.0, 3.0).movers().size(), 0u);
}

TEST(MovingScene, WithoutMoversTheScanIsTheStaticOne) {
    const TriangleMesh static_mesh = wall();
    const RayCaster caster(static_mesh);
    const MovingScene scene(caster, MoverTracks{});
    LidarConfig lidar;
    lidar.num_beams = 16;
    lidar.azimuth_steps = 360;
    lidar.range_noise_sigma_m = 0.02;
    const Eigen::Isometry3d pose(Eigen::Translation3d(0.0, 0.0, 1.7));
    const LidarScan moving = simulate_scan(scene, lidar, pose, 3, 4.0);
    const LidarScan still = simulate_scan(caster, lidar, pose, 3);
    ASSERT_GT(still.points_sensor.size(), 0u);
    EXPECT_EQ(moving.points_sensor, still.points_sensor);
    EXPECT_EQ(moving.triangle_ids, still.triangle_ids);
}

TEST(StreetMovers, DeterministicForASeedWithEveryKind) {
    StreetMoversConfig config;
    config.num_movers = 9;
    const StreetSceneConfig street;
    const MoverTracks a = make_street_movers(config, street, 49.0, 50, 11);
    const MoverTracks b = make_street_movers(config, street, 49.0, 50, 11);
    const MoverTracks c = make_street_movers(config, street, 49.0, 50, 12);
    ASSERT_EQ(a.movers.size(), 9u);
    int cars = 0, cyclists = 0, pedestrians = 0;
    for (std::size_t i = 0; i < a.movers.size(); ++i) {
        EXPECT_EQ(a.movers[i].waypoints.size(), b.movers[i].waypoints.size());
        for (std::size_t k = 0; k < a.movers[i].waypoints.size(); ++k) {
            EXPECT_EQ(a.movers[i].waypoints[k].position_m, b.movers[i].waypoints[k].position_m);
        }
        cars += a.movers[i].kind == MoverKind::kCar;
        cyclists += a.movers[i].kind == MoverKind::kCyclist;
        pedestrians += a.movers[i].kind == MoverKind::kPedestrian;
    }
    EXPECT_EQ(cars, 5);
    EXPECT_EQ(cyclists, 2);
    EXPECT_EQ(pedestrians, 2);
    EXPECT_NE(a.movers[1].waypoints[0].position_m, c.movers[1].waypoints[0].position_m);
    // The parked car stands still, then leaves.
    const MoverTrack& parked = a.movers[0];
    EXPECT_EQ(parked.T_world_body(0.0).translation(), parked.T_world_body(1.0).translation());
    EXPECT_GT(
        parked.T_world_body(5.0).translation().x() - parked.T_world_body(0.0).translation().x(),
        5.0);
}

TEST(StreetMovers, ScansAreDeterministic) {
    StreetSceneConfig street;
    street.length_m = 60.0;
    street.start_x_m = -20.0;
    const StreetScene scene = make_street_scene(street);
    const RayCaster caster(scene.mesh);
    StreetMoversConfig config;
    config.num_movers = 6;
    const MovingScene moving(caster, make_street_movers(config, street, 20.0, 21, 5));
    LidarConfig lidar;
    lidar.num_beams = 16;
    lidar.azimuth_steps = 400;
    lidar.range_noise_sigma_m = 0.01;
    const Eigen::Isometry3d pose(Eigen::Translation3d(10.0, 0.0, 1.73));
    const LidarScan a = simulate_scan(moving, lidar, pose, 9, 1.0);
    const LidarScan b = simulate_scan(moving, lidar, pose, 9, 1.0);
    EXPECT_EQ(a.points_sensor, b.points_sensor);
    EXPECT_EQ(a.triangle_ids, b.triangle_ids);
}

}  // namespace
}  // namespace shine::sim
