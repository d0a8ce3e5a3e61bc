// SE(3) exponential and logarithm (twist order: translation, rotation).
#include "shine/odometry/se3.hpp"

#include <cmath>

namespace shine {

namespace se3_internal {
namespace {

// Below this rotation angle (radians) the coefficients of Rodrigues' formula, of V and of V^-1
// are replaced by their Taylor series (to the t^4 term, whose successor is below 1e-16 here):
// the closed forms of c and d lose digits to cancellation at small angles.
constexpr double kSmallAngleRad = 1e-2;

/// Coefficients of exp: R = I + a [phi]x + b [phi]x^2, V = I + b [phi]x + c [phi]x^2.
struct ExpCoefficients {
    double a, b, c;
};

ExpCoefficients exp_coefficients(double t) {
    const double t2 = t * t;
    if (t < kSmallAngleRad) {
        const double t4 = t2 * t2;
        return {1.0 - t2 / 6.0 + t4 / 120.0, 0.5 - t2 / 24.0 + t4 / 720.0,
                1.0 / 6.0 - t2 / 120.0 + t4 / 5040.0};
    }
    // b = (1 - cos t) / t^2 written as 2 sin^2(t/2) / t^2, free of cancellation.
    const double half_sinc = std::sin(0.5 * t) / (0.5 * t);
    return {std::sin(t) / t, 0.5 * half_sinc * half_sinc, (t - std::sin(t)) / (t2 * t)};
}

}  // namespace
}  // namespace se3_internal

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
    Eigen::Matrix3d m;
    m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
    return m;
}

Eigen::Matrix3d so3_exp(const Eigen::Vector3d& phi) {
    const auto k = se3_internal::exp_coefficients(phi.norm());
    const Eigen::Matrix3d W = skew(phi);
    return Eigen::Matrix3d::Identity() + k.a * W + k.b * W * W;
}

Eigen::Vector3d so3_log(const Eigen::Matrix3d& R) {
    // Through the quaternion: its vector part is sin(t/2) axis, stable at 0 and at pi (where the
    // trace formula acos((tr R - 1) / 2) loses the axis).
    Eigen::Quaterniond q(R);
    q.normalize();
    if (q.w() < 0.0) q.coeffs() = -q.coeffs();  // angle in [0, pi]
    const Eigen::Vector3d v = q.vec();
    const double s = v.norm();
    if (s < 1e-12) return 2.0 * v;  // t = 2 asin(s) ~ 2 s
    const double t = 2.0 * std::atan2(s, q.w());
    return (t / s) * v;
}

Eigen::Isometry3d se3_exp(const Vector6d& xi) {
    const Eigen::Vector3d rho = xi.head<3>();
    const Eigen::Vector3d phi = xi.tail<3>();
    const auto k = se3_internal::exp_coefficients(phi.norm());
    const Eigen::Matrix3d W = skew(phi);
    const Eigen::Matrix3d W2 = W * W;
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::Matrix3d::Identity() + k.a * W + k.b * W2;
    T.translation() = (Eigen::Matrix3d::Identity() + k.b * W + k.c * W2) * rho;
    return T;
}

Vector6d se3_log(const Eigen::Isometry3d& T) {
    const Eigen::Vector3d phi = so3_log(T.linear());
    const double t = phi.norm();
    const Eigen::Matrix3d W = skew(phi);
    // V^-1 = I - 1/2 [phi]x + d [phi]x^2 with d = (1 - a / (2 b)) / t^2 (Barfoot Eq. (7.87)),
    // where a / (2 b) = (t/2) cot(t/2).
    double d;
    const double t2 = t * t;
    if (t < se3_internal::kSmallAngleRad) {
        d = 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0;
    } else {
        d = (1.0 - 0.5 * t / std::tan(0.5 * t)) / t2;
    }
    const Eigen::Matrix3d V_inv = Eigen::Matrix3d::Identity() - 0.5 * W + d * W * W;
    Vector6d xi;
    xi.head<3>() = V_inv * T.translation();
    xi.tail<3>() = phi;
    return xi;
}

Eigen::Isometry3d interpolate_constant_velocity(const Eigen::Isometry3d& T_a_b, double fraction) {
    return se3_exp(fraction * se3_log(T_a_b));
}

Eigen::Isometry3d predict_constant_velocity(const Eigen::Isometry3d& T_world_prev,
                                            const Eigen::Isometry3d& T_world_last) {
    return T_world_last * (T_world_prev.inverse() * T_world_last);
}

double rotation_angle_rad(const Eigen::Isometry3d& T) { return so3_log(T.linear()).norm(); }

}  // namespace shine
