#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "shine/core/error.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/ply.hpp"
#include "shine/sim/drive_trajectory.hpp"
#include "shine/sim/lidar_simulator.hpp"

namespace fs = std::filesystem;

namespace {

using shine::TriangleMesh;
using shine::sim::LidarConfig;
using shine::sim::LidarScan;
using shine::RayCaster;

constexpr double kSensorHeightM = 1.73;
constexpr double kPointToleranceM = 1e-4;  // float storage of points up to ~80 m

/// The plane z = 0 over [-300, 300]^2.
TriangleMesh make_ground_plane() {
    TriangleMesh mesh;
    mesh.vertices = {{-300, -300, 0}, {300, -300, 0}, {300, 300, 0}, {-300, 300, 0}};
    mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
    return mesh;
}

Eigen::Isometry3d pose_at_height(double height_m) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(0.0, 0.0, height_m);
    return T;
}

TEST(LidarSimulator, PlaneBelowSensorGivesExactRanges) {
    const RayCaster caster(make_ground_plane());
    const LidarConfig config;
    // Expected: every ray below the horizon whose plane distance is within [min, max] range.
    std::size_t expected_points = 0;
    std::vector<double> expected_range_of_beam(config.num_beams, -1.0);
    for (int beam = 0; beam < config.num_beams; ++beam) {
        const double dz = shine::sim::lidar_ray_direction(config, beam, 0).z();
        if (dz >= 0.0) continue;
        const double range = kSensorHeightM / -dz;
        if (range < config.min_range_m || range > config.max_range_m) continue;
        expected_range_of_beam[beam] = range;
        expected_points += config.azimuth_steps;
    }
    ASSERT_GT(expected_points, 50u * 1800u);
    const LidarScan scan =
        shine::sim::simulate_scan(caster, config, pose_at_height(kSensorHeightM), 1);
    ASSERT_EQ(scan.points_sensor.size(), expected_points);
    ASSERT_EQ(scan.triangle_ids.size(), expected_points);
    // Points are in beam-major ray order: recover each point's beam from the running index.
    std::size_t i = 0;
    for (int beam = 0; beam < config.num_beams; ++beam) {
        if (expected_range_of_beam[beam] < 0.0) continue;
        for (int step = 0; step < config.azimuth_steps; ++step, ++i) {
            const Eigen::Vector3d p = scan.points_sensor[i].cast<double>();
            const Eigen::Vector3d expected =
                shine::sim::lidar_ray_direction(config, beam, step) * expected_range_of_beam[beam];
            ASSERT_NEAR((p - expected).norm(), 0.0, kPointToleranceM) << "beam " << beam;
            ASSERT_NEAR(p.z(), -kSensorHeightM, kPointToleranceM);
        }
    }
    // The lowest beam (-24.8 deg) hits the road at 1.73 / sin(24.8 deg) = 4.125 m.
    EXPECT_NEAR(expected_range_of_beam.back(), kSensorHeightM / std::sin(24.8 * M_PI / 180.0),
                1e-9);
}

TEST(LidarSimulator, RotatedPosePointsLieOnThePlaneAndMinRangeHolds) {
    const RayCaster caster(make_ground_plane());
    LidarConfig config;
    config.num_beams = 32;
    config.azimuth_steps = 720;
    Eigen::Isometry3d T_world_sensor = pose_at_height(0.6);
    T_world_sensor.linear() = (Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(-0.03, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    T_world_sensor.translation().head<2>() = Eigen::Vector2d(5.0, -3.0);
    const LidarScan scan = shine::sim::simulate_scan(caster, config, T_world_sensor, 1);
    ASSERT_GT(scan.points_sensor.size(), 1000u);
    for (const auto& p : scan.points_sensor) {
        const Eigen::Vector3d p_world = T_world_sensor * p.cast<double>();
        ASSERT_NEAR(p_world.z(), 0.0, kPointToleranceM);
        ASSERT_GE(p.norm(), config.min_range_m - 1e-5);
        ASSERT_LE(p.norm(), config.max_range_m + 1e-5);
    }
}

TEST(LidarSimulator, NoiseIsDeterministicAndHasTheRequestedSigma) {
    const RayCaster caster(make_ground_plane());
    LidarConfig config;
    config.range_noise_sigma_m = 0.05;
    config.min_range_m = 0.0;
    config.max_range_m = 1000.0;
    const LidarScan a =
        shine::sim::simulate_scan(caster, config, pose_at_height(kSensorHeightM), 42);
    const LidarScan b =
        shine::sim::simulate_scan(caster, config, pose_at_height(kSensorHeightM), 42);
    const LidarScan c =
        shine::sim::simulate_scan(caster, config, pose_at_height(kSensorHeightM), 43);
    ASSERT_EQ(a.points_sensor, b.points_sensor);
    ASSERT_EQ(a.points_sensor.size(), c.points_sensor.size());
    EXPECT_NE(a.points_sensor, c.points_sensor);
    // Residual along each ray: measured range - true range (true range from the point's direction).
    double sum = 0.0, sum_sq = 0.0;
    for (const auto& p : a.points_sensor) {
        const Eigen::Vector3d d = p.cast<double>().normalized();
        const double residual = p.cast<double>().norm() - kSensorHeightM / -d.z();
        sum += residual;
        sum_sq += residual * residual;
    }
    const double n = static_cast<double>(a.points_sensor.size());
    const double mean = sum / n;
    const double sigma = std::sqrt(sum_sq / n - mean * mean);
    EXPECT_LT(std::abs(mean), 4.0 * 0.05 / std::sqrt(n));
    EXPECT_NEAR(sigma, 0.05, 0.05 * 0.02);  // 2 %: ~80k samples give ~0.25 % standard error
}

TEST(LidarSimulator, TrajectoryIsSmoothAndRotates) {
    const shine::sim::DriveTrajectoryConfig config;
    const auto poses = shine::sim::make_drive_trajectory(config, 50, 1);
    ASSERT_EQ(poses.size(), 50u);
    double max_yaw = 0.0;
    for (std::size_t i = 0; i < poses.size(); ++i) {
        EXPECT_NEAR(poses[i].translation().z(), config.sensor_height_m, 1e-12);
        EXPECT_LE(std::abs(poses[i].translation().y()), config.weave_amplitude_m + 1e-12);
        const Eigen::Vector3d forward = poses[i].linear().col(0);
        max_yaw = std::max(max_yaw, std::abs(std::atan2(forward.y(), forward.x())));
        if (i > 0) {
            const double step = (poses[i].translation() - poses[i - 1].translation()).norm();
            EXPECT_NEAR(step, 1.0, 0.05);
            const Eigen::AngleAxisd delta(poses[i - 1].linear().transpose() * poses[i].linear());
            EXPECT_LT(delta.angle(), 2.0 * M_PI / 180.0);  // smooth: < 2 deg per frame
        }
    }
    EXPECT_GT(max_yaw, 3.0 * M_PI / 180.0);
    EXPECT_NE(poses[10].translation().y(),
              shine::sim::make_drive_trajectory(config, 50, 2)[10].translation().y());
}

TEST(LidarSimulator, ALaneOffsetMovesTheDriveSidewaysOnly) {
    shine::sim::DriveTrajectoryConfig config;
    const auto centre = shine::sim::make_drive_trajectory(config, 20, 4);
    config.lane_offset_m = -3.0;
    const auto right = shine::sim::make_drive_trajectory(config, 20, 4);
    for (std::size_t i = 0; i < centre.size(); ++i) {
        const Eigen::Vector3d d = right[i].translation() - centre[i].translation();
        EXPECT_NEAR(d.x(), 0.0, 1e-12);
        EXPECT_NEAR(d.y(), -3.0, 1e-12);
        EXPECT_NEAR(d.z(), 0.0, 1e-12);
        EXPECT_TRUE(right[i].linear().isApprox(centre[i].linear(), 1e-12));
    }
    config.lane_offset_m = 3.5;  // 3.5 + 1 m of weave: off the road
    EXPECT_THROW(shine::sim::validate(config), shine::ConfigError);
}

TEST(LidarSimulator, SequenceFilesReadBackAndMarkObservedTriangles) {
    const fs::path dir = fs::path(SHINE_TEST_TMP_DIR) / "sim_sequence";
    fs::remove_all(dir);
    fs::create_directories(dir / "velodyne");
    {  // A stale scan from an earlier, longer run must disappear.
        std::ofstream stale(dir / "velodyne" / "000007.bin", std::ios::binary);
        const float point[4] = {1, 2, 3, 0};
        stale.write(reinterpret_cast<const char*>(point), sizeof(point));
    }
    shine::sim::SimulationConfig config;
    config.seed = 4;
    config.num_frames = 3;
    config.scene_margin_m = 30.0;
    config.lidar.num_beams = 16;
    config.lidar.azimuth_steps = 360;
    config.show_progress = false;
    const auto summary = shine::sim::simulate_sequence(config, dir);
    EXPECT_EQ(summary.num_frames, 3);
    EXPECT_FALSE(fs::exists(dir / "velodyne" / "000007.bin"));
    for (const char* name : {"poses.txt", "gt_mesh.ply", "simulation.json", "README.txt"}) {
        EXPECT_TRUE(fs::exists(dir / name)) << name;
    }
    const auto poses = shine::read_kitti_poses(dir / "poses.txt");
    ASSERT_EQ(poses.size(), 3u);
    for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR(poses[i].translation().x(), i * config.trajectory.frame_spacing_m, 1e-9);
        EXPECT_NEAR(poses[i].translation().z(), config.trajectory.sensor_height_m, 1e-9);
    }
    const TriangleMesh mesh = shine::read_ply_mesh(dir / "gt_mesh.ply");
    ASSERT_EQ(mesh.triangles.size(), summary.num_triangles);
    ASSERT_EQ(mesh.face_observed.size(), mesh.triangles.size());
    std::size_t observed = 0;
    for (const auto o : mesh.face_observed) observed += o != 0;
    EXPECT_EQ(observed, summary.num_observed_triangles);
    EXPECT_GT(observed, 1000u);
    EXPECT_LT(observed, mesh.triangles.size());
    // The street reaches at least the margin beyond the first and last pose.
    Eigen::AlignedBox3f bounds;
    for (const auto& v : mesh.vertices) bounds.extend(v);
    EXPECT_LE(bounds.min().x(), poses.front().translation().x() - config.scene_margin_m + 1e-3);
    EXPECT_GE(bounds.max().x(), poses.back().translation().x() + config.scene_margin_m - 1e-3);

    const RayCaster caster(mesh);
    std::size_t total = 0;
    for (int frame = 0; frame < 3; ++frame) {
        char name[32];
        std::snprintf(name, sizeof(name), "%06d.bin", frame);
        const auto points_sensor = shine::read_kitti_bin(dir / "velodyne" / name);
        ASSERT_GT(points_sensor.size(), 16u * 360u / 2u) << name;
        total += points_sensor.size();
        // Without noise, each point is the first surface along its ray, and its triangle is
        // marked observed.
        for (std::size_t i = 0; i < points_sensor.size(); i += 37) {
            const Eigen::Vector3d p = points_sensor[i].cast<double>();
            const shine::RayHit hit = caster.cast(
                poses[frame].translation(), (poses[frame].linear() * p).normalized(), 0.0, 100.0);
            ASSERT_TRUE(hit.hit());
            EXPECT_NEAR(hit.distance_m, p.norm(), 1e-3);
            EXPECT_EQ(mesh.face_observed[hit.triangle_id], 1);
        }
    }
    EXPECT_EQ(total, summary.total_points);
    EXPECT_THROW(
        {
            shine::sim::SimulationConfig bad = config;
            bad.num_frames = 0;
            shine::sim::simulate_sequence(bad, dir);
        },
        shine::ConfigError);
    EXPECT_THROW(
        {
            shine::sim::SimulationConfig bad = config;
            bad.lidar.range_noise_sigma_m = -0.1;
            shine::sim::simulate_sequence(bad, dir);
        },
        shine::ConfigError);
}

}  // namespace
