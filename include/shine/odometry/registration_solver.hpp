// Levenberg-Marquardt on SE(3) for a scan whose points each have one scalar residual: the common
// core of the SDF registration (residual = the map's SDF at the point) and of point-to-plane ICP
// (residual = the signed distance to the matched point's tangent plane).
//
// The cost is E(T) = sum_i rho(r_i(T p_i)) over the points p_i (sensor frame) whose residual is
// defined at T p_i, with rho a robust kernel. A step perturbs the pose on the right,
// T <- T exp(delta) (se3.hpp), so with g_i the residual's world-frame gradient and R the pose's
// rotation the Jacobian row of point i is
//   J_i = dr_i / d delta = [ (R^T g_i)^T ,  (p_i x R^T g_i)^T ]                         (1)
// (the rotation part follows from d(R exp([phi]x) p)/d phi = -R [p]x). Each iteration solves the
// iteratively reweighted normal equations
//   (H + lambda diag(H)) delta = -b,   H = sum w_i J_i^T J_i,  b = sum w_i J_i^T r_i,      (2)
// w_i = rho'(r_i) / r_i (Marquardt 1963's damping, scaled by the diagonal), and keeps the step
// only if it lowers E; lambda shrinks after a kept step and grows after a refused one.
//
// The sums run over fixed chunks of points in parallel (tbb::parallel_for) and are then added in
// chunk order, so the result is the same bits for any number of threads.
//
// Continuous time (SweepModel): a spinning LiDAR measures its points over a sweep while it
// moves. Point i, measured at sweep fraction s_i (its time over the motion's interval), is then at
// T exp(s_i xi) p_i, where xi is the twist of the motion over the interval (sensor frame at the
// reference time; se3.hpp). The solver then estimates xi with T, as CT-ICP (Dellenbach et al.,
// ICRA 2022) estimates a scan's begin and end poses. With q_i = exp(s_i xi) p_i and the update
// xi <- xi + epsilon, exp(s_i (xi + epsilon)) p_i ~ q_i + s_i (epsilon_rho + epsilon_phi x q_i)
// to first order in s_i xi (a sweep's motion is small), so the Jacobian row of point i is
//   [ J_i(q_i) ,  s_i J_i(q_i) ]                                                        (3)
// with J_i(q_i) Eq. (1) at the deskewed point. A Gaussian prior keeps xi near the expected motion
// xi_0 (the constant-velocity prediction's), adding to E
//   1/2 sum_j (s_kernel / sigma_j)^2 (xi_j - xi_0,j)^2                                  (4)
// as if the residuals had the kernel's scale for a standard deviation: over thousands of points it
// matters only where the data leave the motion unconstrained. Given the previous scan's pose T_p,
// xi_0 follows the pose being solved instead,
//   xi_0(T) = log(T_p^-1 T),   D = d xi_0(T exp(delta)) / d delta (central differences)    (5)
// so that sweep and poses tell one motion (CT-ICP's location consistency where the pose is the
// sweep's end): the prior's Jacobian is [-D, I] in (delta, epsilon). The condition number of the
// registration is still taken on the points' part of H alone.
//
// Success needs three things, reported separately in RegistrationResult: enough points with a
// residual, a well-conditioned H at the solution (its condition number after scaling the rotation
// by the points' RMS range, so that both blocks are in metres: a single plane or a featureless
// corridor leaves directions unconstrained and the number explodes), and a step below the
// convergence thresholds within the iteration budget. On any failure the returned pose is the
// initial one (the caller's prediction): a pose from a diverged or unconstrained solve is worse
// than a constant-velocity guess.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "shine/odometry/se3.hpp"

namespace shine {

/// Shape of the robust kernel rho(r) of the residuals (r in metres).
enum class RobustKernelType : std::uint8_t {
    kL2,           ///< rho = r^2 / 2: no down-weighting
    kHuber,        ///< quadratic up to the scale, linear beyond
    kGemanMcClure  ///< rho = (r^2 / 2) / (1 + r^2 / s^2): outliers far beyond s barely count
};

/// "l2" / "huber" / "geman-mcclure".
const char* to_string(RobustKernelType type);

/// A robust kernel with its scale in metres.
struct RobustKernel {
    RobustKernelType type = RobustKernelType::kGemanMcClure;
    double scale_m = 0.1;  ///< residuals well beyond this are outliers

    /// rho(r).
    double cost(double residual_m) const;
    /// The IRLS weight rho'(r) / r, in (0, 1].
    double weight(double residual_m) const;
};

/// Stopping, damping and acceptance rules of the solver.
struct RegistrationSolverConfig {
    int max_iterations = 30;                ///< Levenberg-Marquardt iterations (linearisations)
    double converged_translation_m = 1e-4;  ///< a step below both thresholds ends the solve
    double converged_rotation_rad = 1e-5;   ///< (1e-5 rad = 0.00057 deg)
    double initial_damping = 1e-4;          ///< lambda of Eq. (2) at the first iteration
    int min_valid_points = 20;              ///< fewer points with a residual: degenerate
    double max_condition_number = 1e4;      ///< of the range-scaled H: beyond it, degenerate
    /// A step below the thresholds is still tried, and taken when it lowers the cost (one more
    /// evaluation of every point). false: the solve ends where it is, without that evaluation;
    /// the pose then differs from the tried step's by less than the thresholds.
    bool try_converged_step = true;
    /// A point whose ray meets its residual's surface at a grazing angle is left out: where
    /// |cos| of the angle between the ray (from the sensor frame's origin to the point, at the
    /// current iterate) and the residual's gradient is below this. Such points carry little of a
    /// pose's constraint and most of a young map's error: ground far from a car is seen only at
    /// grazing angles (odometry_config.hpp). 0 keeps every point.
    double min_incidence_cosine = 0.0;
    RobustKernel kernel;
};

/// The sweep of Eq. (3)-(4): when each point was measured and the motion expected over the sweep.
struct SweepModel {
    /// s_i: point i's time divided by the interval of `twist_prior` (0 at the pose's instant).
    std::vector<float> fractions;
    /// xi_0: the expected motion over one interval, (rho [m], phi [rad]) in the sensor frame.
    Vector6d twist_prior = Vector6d::Zero();
    double prior_sigma_translation_m = 0.05;  ///< sigma_j of Eq. (4) for rho
    double prior_sigma_rotation_rad = 0.01;   ///< sigma_j of Eq. (4) for phi
    /// When set, Eq. (4)'s xi_0 is not twist_prior but the motion from this pose (the previous
    /// scan's, one interval earlier) to the pose being solved, log(T_previous^-1 T) (Eq. (5)).
    /// The sweep still starts at twist_prior.
    std::optional<Eigen::Isometry3d> T_world_previous;
};

/// Why a registration stopped.
enum class RegistrationStatus : std::uint8_t {
    kConverged,       ///< a step below the thresholds, H well conditioned
    kMaxIterations,   ///< the iteration budget ran out
    kTooFewPoints,    ///< fewer than min_valid_points points had a residual
    kIllConditioned,  ///< H's condition number exceeds max_condition_number
    kNoDescent        ///< the damping grew without finding a step that lowers the cost
};

/// "converged" / "max-iterations" / "too-few-points" / "ill-conditioned" / "no-descent".
const char* to_string(RegistrationStatus status);

/// What a registration returns; `T_world_sensor` is the initial pose unless `accepted()`.
struct RegistrationResult {
    Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
    /// The solver's last iterate, kept for diagnostics even when it was not accepted.
    Eigen::Isometry3d T_world_sensor_solved = Eigen::Isometry3d::Identity();
    RegistrationStatus status = RegistrationStatus::kTooFewPoints;
    bool converged = false;     ///< the step fell below the thresholds
    bool degenerate = false;    ///< too few points or an ill-conditioned H
    int iterations = 0;         ///< linearisations of accepted iterates
    double initial_cost = 0.0;  ///< E at the initial pose (sum of rho, m^2)
    double final_cost = 0.0;    ///< E at the returned solve's last iterate
    /// Condition number of the range-scaled H at the last iterate (infinity when singular).
    double condition_number = 0.0;
    std::size_t num_points = 0;  ///< points given
    /// Points used at the last iterate: with a residual and not too oblique (min_incidence_cosine).
    std::size_t num_valid_points = 0;
    /// Points with a residual at the last iterate that were left out as too oblique.
    std::size_t num_oblique_points = 0;
    /// With a SweepModel: the sweep's twist at the last iterate (the prior's when not accepted).
    Vector6d sweep_twist = Vector6d::Zero();

    /// Converged and not degenerate: T_world_sensor is the solve, not the fallback.
    bool accepted() const { return converged && !degenerate; }
    /// One line for logs: status, iterations, costs, condition number, valid points.
    std::string summary() const;
};

/// Residuals of points given in the world frame: for each point its residual r (m), the
/// residual's gradient in the world frame (dimensionless) and valid = 1 when the residual is
/// defined there (0: the point is ignored at this pose). Outputs are resized by the callee.
using PointResiduals = std::function<void(
    const std::vector<Eigen::Vector3d>& points_world, std::vector<double>& residuals_m,
    std::vector<Eigen::Vector3d>& gradients_world, std::vector<std::uint8_t>& valid)>;

/// Minimises sum_i rho(r_i(T p_i)) over T starting at `T_world_sensor_initial`; see the header's
/// comment for the method and the failure rules. With `sweep`, the points are as measured during
/// the sweep and its twist is estimated too (Eq. (3)-(4)), starting at the prior; the condition
/// number is then the pose block's. An empty scan is a kTooFewPoints result, not an error. Throws
/// ConfigError for a non-positive kernel scale, thresholds, iteration count or prior sigma, and
/// DataError when the sweep's fractions do not match the points.
RegistrationResult minimise_point_residuals(const std::vector<Eigen::Vector3f>& points_sensor,
                                            const Eigen::Isometry3d& T_world_sensor_initial,
                                            const PointResiduals& residuals,
                                            const RegistrationSolverConfig& config,
                                            const SweepModel* sweep = nullptr);

/// The normal equations without damping at one pose: of Eq. (2) for N = 6 unknowns, of Eq. (3)
/// for N = 12 (the pose and the sweep's twist).
template <int N>
struct NormalEquationsOf {
    Eigen::Matrix<double, N, N> H = Eigen::Matrix<double, N, N>::Zero();  ///< sum w J^T J
    Eigen::Matrix<double, N, 1> b = Eigen::Matrix<double, N, 1>::Zero();  ///< sum w J^T r
    double cost = 0.0;                                                    ///< sum rho(r)
    double sum_range_sq_m2 = 0.0;  ///< sum |p|^2 over valid points (sensor frame, deskewed)
    std::size_t num_valid = 0;
    std::size_t num_oblique = 0;  ///< with a residual, left out (min_incidence_cosine)
};
/// Eq. (2)'s (for tests and diagnostics).
using NormalEquations = NormalEquationsOf<6>;

/// Eq. (1)-(2) at one pose: the weighted sums over the valid points, in fixed chunks.
NormalEquations build_normal_equations(const std::vector<Eigen::Vector3f>& points_sensor,
                                       const Eigen::Isometry3d& T_world_sensor,
                                       const PointResiduals& residuals, const RobustKernel& kernel);

/// The Jacobian row of Eq. (1) for one point (sensor frame) with world gradient `gradient_world`
/// under the rotation R_world_sensor.
Eigen::Matrix<double, 1, 6> point_residual_jacobian(const Eigen::Vector3d& point_sensor,
                                                    const Eigen::Matrix3d& R_world_sensor,
                                                    const Eigen::Vector3d& gradient_world);

/// Condition number of H after scaling its rotation block by 1 / range_m (so that rotation is
/// measured as arc length at that range): lambda_max / lambda_min, infinity if lambda_min <= 0.
double scaled_condition_number(const Matrix6d& H, double range_m);

}  // namespace shine
