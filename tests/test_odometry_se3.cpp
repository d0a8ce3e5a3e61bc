// SE(3) exponential and logarithm, and constant-velocity interpolation, against closed forms.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "shine/odometry/se3.hpp"

using namespace shine;

namespace {

constexpr double kRoundTripTol = 1e-12;  // dimensionless / m: double rounding of O(1) values
constexpr double kPi = M_PI;

Vector6d twist(double rx, double ry, double rz, double wx, double wy, double wz) {
    Vector6d xi;
    xi << rx, ry, rz, wx, wy, wz;
    return xi;
}

void expect_pose_near(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double tol) {
    EXPECT_LT((a.matrix() - b.matrix()).cwiseAbs().maxCoeff(), tol) << a.matrix() << "\nvs\n"
                                                                    << b.matrix();
}

}  // namespace

TEST(Se3, ExpOfPureRotationMatchesAngleAxisAndTranslationComesFirst) {
    const Eigen::Vector3d axis = Eigen::Vector3d(1, -2, 0.5).normalized();
    const double angle = 1.1;
    const Eigen::Isometry3d T =
        se3_exp(twist(0, 0, 0, angle * axis.x(), angle * axis.y(), angle * axis.z()));
    EXPECT_LT((T.linear() - Eigen::AngleAxisd(angle, axis).toRotationMatrix()).norm(),
              kRoundTripTol);
    EXPECT_LT(T.translation().norm(), kRoundTripTol);
    const Eigen::Isometry3d U = se3_exp(twist(1, 2, 3, 0, 0, 0));
    EXPECT_LT((U.translation() - Eigen::Vector3d(1, 2, 3)).norm(), kRoundTripTol);
    EXPECT_LT((U.linear() - Eigen::Matrix3d::Identity()).norm(), kRoundTripTol);
}

TEST(Se3, ScrewMotionOfAQuarterTurn) {
    // Twist (rho = (v, 0, 0), phi = (0, 0, pi/2)): a quarter circle of radius v / (pi/2) about z,
    // starting along +x, ends at (r, r, 0).
    const double v = 2.0;
    const Eigen::Isometry3d T = se3_exp(twist(v, 0, 0, 0, 0, kPi / 2));
    const double r = v / (kPi / 2);
    EXPECT_LT((T.translation() - Eigen::Vector3d(r, r, 0)).norm(), kRoundTripTol);
}

TEST(Se3, LogInvertsExpForRandomTwistsSmallAndNearPiAngles) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    int checked = 0;
    for (const double angle : {0.0, 1e-9, 1e-5, 1e-3, 0.3, 1.5, 3.0, kPi - 1e-6}) {
        for (int k = 0; k < 20; ++k) {
            const Eigen::Vector3d axis = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized();
            Vector6d xi;
            xi.head<3>() = 10.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
            xi.tail<3>() = angle * axis;
            const Vector6d back = se3_log(se3_exp(xi));
            // Near pi, the axis of a rotation by pi - 1e-6 keeps ~1e-10 of precision.
            const double tol = angle > 3.1 ? 1e-8 : 1e-11;
            EXPECT_LT((back - xi).norm(), tol * (1.0 + xi.norm())) << "angle " << angle;
            ++checked;
        }
    }
    EXPECT_EQ(checked, 160);
}

TEST(Se3, ExpIsSmoothThroughTheSmallAngleSwitch) {
    // Just below and above the Taylor switch (1e-2 rad) both forms give the same motion as
    // composing many tiny steps would: compare with exp(xi / 2)^2, which is evaluated on the
    // other side of the switch.
    for (const double angle : {0.99e-2, 1.0e-2, 1.01e-2, 1.98e-2, 2.02e-2}) {
        const Vector6d xi = twist(1, 2, 3, 0.3 * angle, -0.4 * angle, std::sqrt(0.75) * angle);
        const Eigen::Isometry3d half = se3_exp(0.5 * xi);
        expect_pose_near(se3_exp(xi), half * half, kRoundTripTol);
        const Eigen::Matrix3d R =
            Eigen::AngleAxisd(angle, xi.tail<3>().normalized()).toRotationMatrix();
        EXPECT_LT((se3_exp(xi).linear() - R).norm(), kRoundTripTol) << angle;
    }
}

TEST(Se3, InterpolationAlongConstantVelocity) {
    const Eigen::Isometry3d T = se3_exp(twist(1.5, -0.3, 0.2, 0.05, -0.1, 0.4));
    expect_pose_near(interpolate_constant_velocity(T, 0.0), Eigen::Isometry3d::Identity(),
                     kRoundTripTol);
    expect_pose_near(interpolate_constant_velocity(T, 1.0), T, kRoundTripTol);
    expect_pose_near(interpolate_constant_velocity(T, -1.0), T.inverse(), kRoundTripTol);
    const Eigen::Isometry3d half = interpolate_constant_velocity(T, 0.5);
    expect_pose_near(half * half, T, kRoundTripTol);
    const Eigen::Isometry3d third = interpolate_constant_velocity(T, 1.0 / 3.0);
    expect_pose_near(third * third * third, T, kRoundTripTol);
    expect_pose_near(interpolate_constant_velocity(T, 2.0), T * T, kRoundTripTol);
}

TEST(Se3, ConstantVelocityPredictionRepeatsTheLastMotion) {
    const Eigen::Isometry3d step = se3_exp(twist(1.0, 0.1, 0, 0, 0, 0.02));
    const Eigen::Isometry3d T0 = se3_exp(twist(100, -50, 3, 0.1, 0.2, 2.0));
    const Eigen::Isometry3d T1 = T0 * step;
    expect_pose_near(predict_constant_velocity(T0, T1), T1 * step, 1e-10);
    EXPECT_NEAR(rotation_angle_rad(step), 0.02, kRoundTripTol);
}
