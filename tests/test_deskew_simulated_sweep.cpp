// Deskew on a simulated distorted sweep: a LiDAR moving during its 0.1 s sweep inside a box room
// (sim::SweepMotion), its points moved to the instant of the scan's pose by odometry's
// deskew_scan, must land on the room's walls as seen from that pose; the distorted points must
// not. The same with the street simulator's drive (a weaving, pitching, rolling path whose
// velocity is not constant) deskewed with the motion between consecutive frames.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "shine/geometry/ray_caster.hpp"
#include "shine/odometry/scan_deskew.hpp"
#include "shine/odometry/se3.hpp"
#include "shine/sim/drive_trajectory.hpp"
#include "shine/sim/lidar_simulator.hpp"
#include "shine/sim/mesh_primitives.hpp"

namespace {

using shine::RayCaster;
using shine::sim::LidarConfig;
using shine::sim::LidarScan;
using shine::sim::SweepMotion;

constexpr double kSweepS = 0.1;  // 10 Hz

// Measured (constant twist, 10 m/s and 20 deg/s), distance to the nearest wall: deskewed max
// 0.002 mm (float32 points), distorted 95th percentile 687 mm, max 1.62 m. Bounds:
constexpr double kDeskewedMaxErrorM = 0.001;  // 1 mm
constexpr double kDistortedP95ErrorM = 0.2;   // 20 cm: distortion is far beyond it
// Measured on the street's drive (10 m/s, lane weave, pitch and roll oscillations), distance to
// the nearest wall: deskewed with the motion to the next frame max 11.9 mm (95th percentile
// 5.1 mm); with the previous frame's motion (all online odometry has) 95th percentile 30.5 mm,
// max 108 mm; distorted 95th percentile 449 mm. Bounds:
constexpr double kDriveBetweenMaxErrorM = 0.025;  // 2.5 cm
constexpr double kDrivePreviousP95ErrorM = 0.06;  // 6 cm

LidarConfig small_lidar() {
    LidarConfig lidar;
    lidar.num_beams = 16;
    lidar.elevation_max_deg = 10.0;
    lidar.elevation_min_deg = -20.0;
    lidar.azimuth_steps = 720;
    lidar.max_range_m = 100.0;
    return lidar;
}

constexpr float kRoomMin[3] = {-30.0f, -15.0f, -0.5f};
constexpr float kRoomMax[3] = {50.0f, 15.0f, 8.0f};

/// A room 80 m long, 30 m wide, 8 m high around the sensor's path.
RayCaster& room() {
    static RayCaster caster(
        shine::sim::make_box_mesh(Eigen::Vector3f(kRoomMin[0], kRoomMin[1], kRoomMin[2]),
                                  Eigen::Vector3f(kRoomMax[0], kRoomMax[1], kRoomMax[2])));
    return caster;
}

/// How far each point (sensor frame at the reference pose T_world_ref) lies from the room's walls,
/// floor and ceiling: the distance to the box's surface, inside or out.
std::vector<double> wall_errors(const std::vector<Eigen::Vector3f>& points_ref,
                                const Eigen::Isometry3d& T_world_ref) {
    std::vector<double> errors;
    for (const Eigen::Vector3f& p : points_ref) {
        const Eigen::Vector3d q = T_world_ref * p.cast<double>();
        double inside = 1e9;
        Eigen::Vector3d outside = Eigen::Vector3d::Zero();
        for (int a = 0; a < 3; ++a) {
            inside = std::min({inside, q[a] - kRoomMin[a], kRoomMax[a] - q[a]});
            outside[a] = std::max({0.0, kRoomMin[a] - q[a], q[a] - kRoomMax[a]});
        }
        errors.push_back(outside.norm() > 0.0 ? outside.norm() : inside);
    }
    return errors;
}

double max_of(const std::vector<double>& v) { return *std::max_element(v.begin(), v.end()); }

double percentile(std::vector<double> v, double p) {
    std::sort(v.begin(), v.end());
    return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))];
}

double percentile_95(const std::vector<double>& v) { return percentile(v, 0.95); }

void print_errors(const char* what, const std::vector<double>& e) {
    std::printf("%s: median %.6f p95 %.6f p99 %.6f max %.6f m (%zu points)\n", what,
                percentile(e, 0.5), percentile(e, 0.95), percentile(e, 0.99), max_of(e), e.size());
}

}  // namespace

TEST(DeskewSimulatedSweep, ConstantTwistLandsOnTheWallsOnlyWhenDeskewed) {
    const LidarConfig lidar = small_lidar();
    Eigen::Isometry3d T_world_ref = Eigen::Isometry3d::Identity();
    T_world_ref.translation() = Eigen::Vector3d(0.0, 1.0, 1.7);
    // 10 m/s forward, 20 deg/s yaw, a little roll: one constant body twist.
    shine::Vector6d twist_per_s;
    twist_per_s << 10.0, 0.0, 0.0, 0.02, 0.0, 20.0 * M_PI / 180.0;
    SweepMotion motion;
    motion.sweep_s = kSweepS;
    for (int j = 0; j < lidar.azimuth_steps; ++j) {
        const double t_s = kSweepS * j / lidar.azimuth_steps;
        motion.T_world_sensor.push_back(T_world_ref * shine::se3_exp(t_s * twist_per_s));
    }
    const LidarScan scan = shine::sim::simulate_scan(room(), lidar, motion, 7);
    ASSERT_GT(scan.points_sensor.size(), 10000u);
    ASSERT_EQ(scan.point_time_s.size(), scan.points_sensor.size());
    EXPECT_DOUBLE_EQ(scan.point_time_s.front(), 0.0);
    EXPECT_LT(scan.point_time_s.back(), kSweepS);

    const Eigen::Isometry3d T_prev_cur = shine::se3_exp(kSweepS * twist_per_s);
    const auto deskewed =
        shine::deskew_scan(scan.points_sensor, scan.point_time_s, T_prev_cur, kSweepS);
    const std::vector<double> fixed = wall_errors(deskewed, T_world_ref);
    const std::vector<double> distorted = wall_errors(scan.points_sensor, T_world_ref);
    print_errors("deskewed", fixed);
    print_errors("distorted", distorted);
    EXPECT_LT(max_of(fixed), kDeskewedMaxErrorM);
    EXPECT_GT(percentile_95(distorted), kDistortedP95ErrorM);
}

TEST(DeskewSimulatedSweep, StreetDriveDeskewedWithTheMotionBetweenFrames) {
    const LidarConfig lidar = small_lidar();
    const shine::sim::DriveTrajectoryConfig drive;  // 1 m per 0.1 s frame: 10 m/s
    constexpr std::uint64_t kSeed = 3;
    constexpr int kFrame = 5;
    SweepMotion motion;
    motion.sweep_s = kSweepS;
    for (int j = 0; j < lidar.azimuth_steps; ++j) {
        const double frame = kFrame + double(j) / lidar.azimuth_steps;
        motion.T_world_sensor.push_back(
            shine::sim::drive_pose_at(drive, kSeed, frame * drive.frame_spacing_m));
    }
    // drive_pose_at agrees with make_drive_trajectory's frames bit for bit.
    const auto frames = shine::sim::make_drive_trajectory(drive, kFrame + 2, kSeed);
    EXPECT_TRUE(frames[kFrame].isApprox(motion.T_world_sensor.front(), 0.0));

    const LidarScan scan = shine::sim::simulate_scan(room(), lidar, motion, 11);
    const Eigen::Isometry3d& T_world_ref = frames[kFrame];
    const Eigen::Isometry3d T_prev_cur = frames[kFrame - 1].inverse() * frames[kFrame];
    const Eigen::Isometry3d T_cur_next = frames[kFrame].inverse() * frames[kFrame + 1];
    // Given poses: the sweep runs from this frame's pose to the next one's.
    const std::vector<double> between =
        wall_errors(shine::deskew_scan_between(scan.points_sensor, scan.point_time_s, T_prev_cur,
                                               kSweepS, T_cur_next, kSweepS),
                    T_world_ref);
    // Estimated poses, online: only the motion from the previous frame is known.
    const std::vector<double> previous =
        wall_errors(shine::deskew_scan(scan.points_sensor, scan.point_time_s, T_prev_cur, kSweepS),
                    T_world_ref);
    const std::vector<double> distorted = wall_errors(scan.points_sensor, T_world_ref);
    print_errors("deskewed, motion to the next frame", between);
    print_errors("deskewed, motion from the previous frame", previous);
    print_errors("distorted", distorted);
    EXPECT_LT(max_of(between), kDriveBetweenMaxErrorM);
    EXPECT_LT(percentile_95(previous), kDrivePreviousP95ErrorM);
    EXPECT_GT(percentile_95(distorted), kDistortedP95ErrorM);
}
