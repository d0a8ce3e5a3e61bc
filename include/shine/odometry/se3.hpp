// Rigid motions as 6-vectors: the exponential and logarithm of SE(3), and the pose of a sensor
// moving at constant velocity.
//
// A twist is xi = (rho, phi): translation part rho (metres) FIRST, rotation part phi (radians, an
// axis times an angle) second. exp(xi) = [R(phi) | V(phi) rho] with R Rodrigues' rotation and
//   V(phi) = I + (1 - cos t) / t^2 [phi]x + (t - sin t) / t^3 [phi]x^2,   t = |phi|
// (Barfoot, "State Estimation for Robotics", 2017, Eq. (7.86)); log is its inverse for rotation
// angles in [0, pi]. Near t = 0 the coefficients switch to their Taylor series, so both functions
// are smooth and exact to double rounding at the identity.
//
// Registration perturbs a pose on the right, T_world_sensor * exp(delta): delta is a twist in the
// sensor frame, whose lever arms are the (short) sensor-frame ranges rather than world coordinates
// that may be kilometres from the origin.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace shine {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

/// [v]x, the matrix of the cross product v x (.).
Eigen::Matrix3d skew(const Eigen::Vector3d& v);

/// Rotation of the axis-angle vector `phi` (radians): Rodrigues' formula.
Eigen::Matrix3d so3_exp(const Eigen::Vector3d& phi);

/// Axis-angle vector of rotation `R` (angle in [0, pi]); exact also near 0 and pi.
Eigen::Vector3d so3_log(const Eigen::Matrix3d& R);

/// The rigid motion of twist `xi` = (rho [m], phi [rad]).
Eigen::Isometry3d se3_exp(const Vector6d& xi);

/// The twist (rho [m], phi [rad]) of `T`: se3_exp(se3_log(T)) == T up to rounding.
Vector6d se3_log(const Eigen::Isometry3d& T);

/// Pose at `fraction` of the way along the constant-velocity motion `T_a_b` (the screw motion of
/// constant body twist that takes frame a to frame b in one unit of time): exp(fraction log T_a_b).
/// fraction 0 gives the identity, 1 gives T_a_b, -1 its inverse; any real fraction extrapolates.
Eigen::Isometry3d interpolate_constant_velocity(const Eigen::Isometry3d& T_a_b, double fraction);

/// Constant-velocity prediction of the next pose from the last two: T_world_prev and
/// T_world_last are consecutive poses; returns T_world_last * (T_world_prev^-1 T_world_last).
Eigen::Isometry3d predict_constant_velocity(const Eigen::Isometry3d& T_world_prev,
                                            const Eigen::Isometry3d& T_world_last);

/// Rotation angle of `T` in radians, in [0, pi].
double rotation_angle_rad(const Eigen::Isometry3d& T);

}  // namespace shine
