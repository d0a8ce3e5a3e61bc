// Per-point times from the azimuth (io/sweep_times.hpp): on a simulated spinning LiDAR whose
// sensor moves during the sweep, the times inferred from the points' azimuths must be the
// simulator's own per-point times, given the simulator's sweep (counter-clockwise from +x, the
// pose at the start); and the KITTI convention (clockwise from the back, the pose facing
// forward) must place the sweep's quarters where that convention puts them.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/geometry/ray_caster.hpp"
#include "shine/io/sweep_times.hpp"
#include "shine/odometry/se3.hpp"
#include "shine/sim/lidar_simulator.hpp"
#include "shine/sim/mesh_primitives.hpp"

namespace {

constexpr double kSweepS = 0.1;  // 10 Hz
constexpr int kAzimuthSteps = 720;
// A ray's time is its azimuth step's; its point's azimuth is the ray's up to float rounding, so
// the inferred time may differ by rounding, or by a whole sweep for a ray fired exactly at the
// cut (+x), whose point may fall a hair on either side of it. Bound: a thousandth of a step.
constexpr double kTimeToleranceS = 1e-3 * kSweepS / kAzimuthSteps;

/// The circular difference of two times in one sweep.
double sweep_difference_s(double a, double b) {
    const double d = std::fmod(std::abs(a - b), kSweepS);
    return std::min(d, kSweepS - d);
}

}  // namespace

TEST(SweepTimes, SimulatedMovingSweepTimesAreRecoveredFromTheAzimuth) {
    shine::sim::LidarConfig lidar;
    lidar.num_beams = 16;
    lidar.elevation_max_deg = 10.0;
    lidar.elevation_min_deg = -20.0;
    lidar.azimuth_steps = kAzimuthSteps;
    lidar.max_range_m = 100.0;
    const shine::RayCaster room(shine::sim::make_box_mesh(Eigen::Vector3f(-30.0f, -15.0f, -0.5f),
                                                          Eigen::Vector3f(50.0f, 15.0f, 8.0f)));
    // 10 m/s forward and 20 deg/s of yaw during the sweep: the points are measured in the moving
    // sensor frame, as a real spinning LiDAR measures them.
    shine::Vector6d twist_per_s;
    twist_per_s << 10.0, 0.0, 0.0, 0.0, 0.0, 20.0 * M_PI / 180.0;
    Eigen::Isometry3d T_world_start = Eigen::Isometry3d::Identity();
    T_world_start.translation() = Eigen::Vector3d(0.0, 1.0, 1.7);
    shine::sim::SweepMotion motion;
    motion.sweep_s = kSweepS;
    for (int j = 0; j < kAzimuthSteps; ++j) {
        motion.T_world_sensor.push_back(T_world_start *
                                        shine::se3_exp(kSweepS * j / kAzimuthSteps * twist_per_s));
    }
    const shine::sim::LidarScan scan = shine::sim::simulate_scan(room, lidar, motion, 3);
    ASSERT_GT(scan.points_sensor.size(), 10000u);
    ASSERT_EQ(scan.point_time_s.size(), scan.points_sensor.size());

    shine::SweepTimeModel simulator_sweep;
    simulator_sweep.direction = shine::SweepDirection::kCounterClockwise;
    simulator_sweep.start_azimuth_deg = 0.0;
    simulator_sweep.pose_azimuth_deg = 0.0;
    simulator_sweep.sweep_period_s = kSweepS;
    const std::vector<double> times_s =
        shine::sweep_point_times_s(scan.points_sensor, simulator_sweep);
    ASSERT_EQ(times_s.size(), scan.points_sensor.size());
    double worst_s = 0.0;
    for (std::size_t i = 0; i < times_s.size(); ++i) {
        ASSERT_TRUE(std::isfinite(times_s[i]));
        EXPECT_GE(times_s[i], 0.0);
        EXPECT_LT(times_s[i], kSweepS);
        worst_s = std::max(worst_s, sweep_difference_s(times_s[i], scan.point_time_s[i]));
    }
    EXPECT_LE(worst_s, kTimeToleranceS);

    // The opposite direction gets the times wrong: the check above can fail.
    simulator_sweep.direction = shine::SweepDirection::kClockwise;
    const std::vector<double> wrong_s =
        shine::sweep_point_times_s(scan.points_sensor, simulator_sweep);
    std::size_t wrong = 0;
    for (std::size_t i = 0; i < wrong_s.size(); ++i) {
        if (sweep_difference_s(wrong_s[i], scan.point_time_s[i]) > 0.01) ++wrong;
    }
    EXPECT_GT(wrong, times_s.size() / 2);
}

TEST(SweepTimes, KittiConventionTurnsClockwiseFromTheBackWithThePoseFacingForward) {
    const shine::SweepTimeModel kitti;  // the defaults
    const std::vector<Eigen::Vector3f> points = {
        {10.0f, 0.0f, 0.0f},     // forward: the pose's instant
        {0.0f, 10.0f, -1.0f},    // left: a quarter turn before it
        {0.0f, -10.0f, 1.0f},    // right: a quarter turn after it
        {-10.0f, 0.01f, 0.0f},   // just left of the back: the sweep's start
        {-10.0f, -0.01f, 0.0f},  // just right of the back: its end
        {0.0f, 0.0f, 5.0f},      // on the spin axis: no motion to undo
        {NAN, 1.0f, 1.0f}};
    const std::vector<double> t = shine::sweep_point_times_s(points, kitti);
    constexpr double kTolS = 1e-4;  // the +-0.01 m offsets at 10 m: 0.06 deg, 1.6e-5 s
    EXPECT_NEAR(t[0], 0.0, kTolS);
    EXPECT_NEAR(t[1], -0.025, kTolS);
    EXPECT_NEAR(t[2], 0.025, kTolS);
    EXPECT_NEAR(t[3], -0.05, kTolS);
    EXPECT_NEAR(t[4], 0.05, kTolS);
    EXPECT_EQ(t[5], 0.0);
    EXPECT_TRUE(std::isnan(t[6]));
}

TEST(SweepTimes, RejectsABadPeriodAndParsesDirections) {
    shine::SweepTimeModel model;
    model.sweep_period_s = 0.0;
    EXPECT_THROW(shine::sweep_point_times_s({{1.0f, 0.0f, 0.0f}}, model), shine::ConfigError);
    model.sweep_period_s = 0.1;
    model.start_azimuth_deg = NAN;
    EXPECT_THROW(shine::sweep_point_times_s({{1.0f, 0.0f, 0.0f}}, model), shine::ConfigError);
    EXPECT_EQ(shine::parse_sweep_direction("ccw", "k"), shine::SweepDirection::kCounterClockwise);
    EXPECT_EQ(shine::parse_sweep_direction("clockwise", "k"), shine::SweepDirection::kClockwise);
    EXPECT_THROW(shine::parse_sweep_direction("left", "deskew.sweep_direction"),
                 shine::ConfigError);
}
