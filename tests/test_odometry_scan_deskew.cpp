// Deskew of a sweep distorted by a known constant-velocity motion.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "shine/core/error.hpp"
#include "shine/odometry/scan_deskew.hpp"
#include "shine/odometry/se3.hpp"

using namespace shine;

namespace {

constexpr double kPointTolM = 1e-5;  // 10 um: float storage of points 30 m away

}  // namespace

TEST(ScanDeskew, UndoesTheDistortionOfAConstantVelocitySweep) {
    // A car at 15 m/s turning at 20 deg/s, 10 Hz sweep; point times in [-0.1, 0] s with the
    // reference at the sweep's end.
    Vector6d velocity;  // body twist per second: (m/s, rad/s)
    velocity << 15.0, 0.3, 0.1, 0.01, -0.02, 20.0 * M_PI / 180.0;
    const double interval_s = 0.1;
    const Eigen::Isometry3d T_world_ref = se3_exp((Vector6d() << 200, -40, 2, 0, 0, 1).finished());

    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-30.0, 30.0);
    std::vector<Eigen::Vector3d> points_world;
    std::vector<Eigen::Vector3f> measured, expected;
    std::vector<double> times;
    const int n = 2000;
    for (int i = 0; i < n; ++i) {
        const Eigen::Vector3d x = T_world_ref * Eigen::Vector3d(u(rng), u(rng), 0.1 * u(rng));
        const double t = -interval_s * (1.0 - double(i) / (n - 1));  // the sweep's order
        const Eigen::Isometry3d T_world_t = T_world_ref * se3_exp(t * velocity);
        measured.push_back((T_world_t.inverse() * x).cast<float>());
        expected.push_back((T_world_ref.inverse() * x).cast<float>());
        times.push_back(t);
    }
    const Eigen::Isometry3d T_prev_cur = se3_exp(interval_s * velocity);
    const std::vector<Eigen::Vector3f> deskewed =
        deskew_scan(measured, times, T_prev_cur, interval_s);
    ASSERT_EQ(deskewed.size(), expected.size());
    double max_error = 0.0, max_distortion = 0.0;
    for (int i = 0; i < n; ++i) {
        max_error = std::max(max_error, double((deskewed[i] - expected[i]).norm()));
        max_distortion = std::max(max_distortion, double((measured[i] - expected[i]).norm()));
    }
    EXPECT_LT(max_error, kPointTolM);
    EXPECT_GT(max_distortion, 1.5);  // the first points were ~1.5 m away: the test has teeth
}

TEST(ScanDeskew, PointsAtTheReferenceTimeDoNotMoveAndPoseAtMinusIntervalIsThePrevious) {
    const Eigen::Isometry3d T_prev_cur =
        se3_exp((Vector6d() << 1.0, 0.2, 0.0, 0.0, 0.0, 0.05).finished());
    const std::vector<Eigen::Vector3f> points = {{1, 2, 3}, {-4, 5, 0.5f}};
    const auto out = deskew_scan(points, {0.0, 0.0}, T_prev_cur, 0.1);
    EXPECT_EQ(out[0], points[0]);
    EXPECT_EQ(out[1], points[1]);
    const Eigen::Isometry3d back = sensor_pose_at(T_prev_cur, 0.1, -0.1);
    EXPECT_LT((back.matrix() - T_prev_cur.inverse().matrix()).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(ScanDeskew, BetweenUsesTheMotionOnEachSideOfTheReference) {
    // Before the reference the car drove straight at 10 m/s, after it it turns at 30 deg/s.
    Vector6d before, after;
    before << 10.0, 0.0, 0.0, 0.0, 0.0, 0.0;
    after << 10.0, 0.0, 0.0, 0.0, 0.0, 30.0 * M_PI / 180.0;
    const double interval_s = 0.1;
    std::vector<Eigen::Vector3f> measured, expected;
    std::vector<double> times;
    for (int i = 0; i <= 20; ++i) {
        const double t = -0.05 + 0.005 * i;
        const Eigen::Vector3d x(20.0 * std::cos(i), 20.0 * std::sin(i), 1.0);  // reference frame
        const Eigen::Isometry3d T_ref_t = se3_exp(t * (t < 0.0 ? before : after));
        measured.push_back((T_ref_t.inverse() * x).cast<float>());
        expected.push_back(x.cast<float>());
        times.push_back(t);
    }
    const auto out = deskew_scan_between(measured, times, se3_exp(interval_s * before), interval_s,
                                         se3_exp(interval_s * after), interval_s);
    double max_error = 0.0;
    for (std::size_t i = 0; i < out.size(); ++i) {
        max_error = std::max(max_error, double((out[i] - expected[i]).norm()));
    }
    EXPECT_LT(max_error, kPointTolM);
    // One velocity for the whole sweep (either side's) misses the other side's points.
    const auto one = deskew_scan(measured, times, se3_exp(interval_s * before), interval_s);
    EXPECT_GT(double((one.back() - expected.back()).norm()), 0.1);
    EXPECT_THROW(deskew_scan_between(measured, times, Eigen::Isometry3d::Identity(), 0.1,
                                     Eigen::Isometry3d::Identity(), 0.0),
                 ConfigError);
}

TEST(ScanDeskew, MismatchedTimesOrIntervalAreErrors) {
    const std::vector<Eigen::Vector3f> points = {{1, 2, 3}};
    EXPECT_THROW(deskew_scan(points, {0.0, 0.1}, Eigen::Isometry3d::Identity(), 0.1), DataError);
    EXPECT_THROW(deskew_scan(points, {0.0}, Eigen::Isometry3d::Identity(), 0.0), ConfigError);
}
