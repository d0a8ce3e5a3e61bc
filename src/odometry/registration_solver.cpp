// Levenberg-Marquardt on SE(3) over per-point scalar residuals, with deterministic parallel sums.
#include "shine/odometry/registration_solver.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstdio>
#include <limits>

#include "shine/core/error.hpp"

namespace shine {

namespace registration_solver_internal {
namespace {

/// Points per chunk of the sums: fixed, so that the order of the additions (within a chunk, then
/// chunk after chunk) does not depend on the number of threads.
constexpr std::size_t kChunkPoints = 256;

/// Smallest diagonal entry of the damping, relative to the largest one.
constexpr double kDampingFloor = 1e-6;

/// The damping after which the solver gives up looking for a descent step.
constexpr double kMaxDamping = 1e8;

void check_config(const RegistrationSolverConfig& config) {
    if (!(config.kernel.scale_m > 0.0)) {
        throw ConfigError("registration kernel scale_m must be positive (got " +
                          std::to_string(config.kernel.scale_m) + ")");
    }
    if (config.max_iterations < 1) {
        throw ConfigError("registration max_iterations must be at least 1 (got " +
                          std::to_string(config.max_iterations) + ")");
    }
    if (!(config.converged_translation_m > 0.0) || !(config.converged_rotation_rad > 0.0)) {
        throw ConfigError(
            "registration converged_translation_m and converged_rotation_rad must be positive");
    }
    if (!(config.max_condition_number > 1.0)) {
        throw ConfigError("registration max_condition_number must exceed 1 (got " +
                          std::to_string(config.max_condition_number) + ")");
    }
    if (!(config.initial_damping >= 0.0)) {
        throw ConfigError("registration initial_damping must be >= 0");
    }
    if (!(config.min_incidence_cosine >= 0.0 && config.min_incidence_cosine <= 1.0)) {
        throw ConfigError("registration min_incidence_cosine must be in [0, 1] (got " +
                          std::to_string(config.min_incidence_cosine) + ")");
    }
}

}  // namespace
}  // namespace registration_solver_internal

const char* to_string(RobustKernelType type) {
    switch (type) {
        case RobustKernelType::kL2:
            return "l2";
        case RobustKernelType::kHuber:
            return "huber";
        case RobustKernelType::kGemanMcClure:
            return "geman-mcclure";
    }
    return "?";
}

const char* to_string(RegistrationStatus status) {
    switch (status) {
        case RegistrationStatus::kConverged:
            return "converged";
        case RegistrationStatus::kMaxIterations:
            return "max-iterations";
        case RegistrationStatus::kTooFewPoints:
            return "too-few-points";
        case RegistrationStatus::kIllConditioned:
            return "ill-conditioned";
        case RegistrationStatus::kNoDescent:
            return "no-descent";
    }
    return "?";
}

double RobustKernel::cost(double r) const {
    const double r2 = r * r;
    switch (type) {
        case RobustKernelType::kL2:
            return 0.5 * r2;
        case RobustKernelType::kHuber: {
            const double a = std::abs(r);
            return a <= scale_m ? 0.5 * r2 : scale_m * (a - 0.5 * scale_m);
        }
        case RobustKernelType::kGemanMcClure:
            return 0.5 * r2 / (1.0 + r2 / (scale_m * scale_m));
    }
    return 0.5 * r2;
}

double RobustKernel::weight(double r) const {
    switch (type) {
        case RobustKernelType::kL2:
            return 1.0;
        case RobustKernelType::kHuber: {
            const double a = std::abs(r);
            return a <= scale_m ? 1.0 : scale_m / a;
        }
        case RobustKernelType::kGemanMcClure: {
            // d/dr of (r^2/2) / (1 + r^2/s^2) is r / (1 + r^2/s^2)^2.
            const double d = 1.0 + r * r / (scale_m * scale_m);
            return 1.0 / (d * d);
        }
    }
    return 1.0;
}

std::string RegistrationResult::summary() const {
    char buf[256];
    std::snprintf(buf, sizeof(buf),
                  "%s after %d iterations, cost %.6g -> %.6g, condition number %.3g, %zu of %zu "
                  "points valid%s",
                  to_string(status), iterations, initial_cost, final_cost, condition_number,
                  num_valid_points, num_points, accepted() ? "" : " (kept the initial pose)");
    return buf;
}

Eigen::Matrix<double, 1, 6> point_residual_jacobian(const Eigen::Vector3d& point_sensor,
                                                    const Eigen::Matrix3d& R_world_sensor,
                                                    const Eigen::Vector3d& gradient_world) {
    // Eq. (1).
    const Eigen::Vector3d g_sensor = R_world_sensor.transpose() * gradient_world;
    Eigen::Matrix<double, 1, 6> J;
    J.head<3>() = g_sensor.transpose();
    J.tail<3>() = point_sensor.cross(g_sensor).transpose();
    return J;
}

namespace registration_solver_internal {
namespace {

/// The sums of Eq. (2) (N = 6) or of Eq. (3) (N = 12: `sweep` and `sweep_twist` given) at pose T,
/// over fixed chunks of points; Eq. (4)'s prior is not included.
template <int N>
NormalEquationsOf<N> build_equations(const std::vector<Eigen::Vector3f>& points_sensor,
                                     const Eigen::Isometry3d& T_world_sensor,
                                     const PointResiduals& residuals, const RobustKernel& kernel,
                                     double min_incidence_cosine, const SweepModel* sweep,
                                     const Vector6d& sweep_twist) {
    const std::size_t n = points_sensor.size();
    NormalEquationsOf<N> total;
    if (n == 0) return total;
    // The points where the solver sees them: as given (N = 6), or deskewed along the sweep's
    // twist (N = 12, computed once per call).
    std::vector<Eigen::Vector3d> deskewed;
    if constexpr (N == 12) {
        deskewed.resize(n);
        tbb::parallel_for(std::size_t(0), n, [&](std::size_t i) {
            deskewed[i] = se3_exp(double(sweep->fractions[i]) * sweep_twist) *
                          points_sensor[i].cast<double>();
        });
    }
    const auto point_ref = [&](std::size_t i) -> Eigen::Vector3d {
        if constexpr (N == 12) return deskewed[i];
        return points_sensor[i].cast<double>();
    };
    std::vector<Eigen::Vector3d> points_world(n);
    for (std::size_t i = 0; i < n; ++i) points_world[i] = T_world_sensor * point_ref(i);
    std::vector<double> r;
    std::vector<Eigen::Vector3d> g;
    std::vector<std::uint8_t> valid;
    residuals(points_world, r, g, valid);
    if (r.size() != n || g.size() != n || valid.size() != n) {
        throw DataError("registration: the residual function returned " + std::to_string(r.size()) +
                        " residuals for " + std::to_string(n) + " points");
    }
    const Eigen::Matrix3d R = T_world_sensor.linear();
    const std::size_t num_chunks = (n + kChunkPoints - 1) / kChunkPoints;
    std::vector<NormalEquationsOf<N>> partial(num_chunks);
    tbb::parallel_for(std::size_t(0), num_chunks, [&](std::size_t c) {
        NormalEquationsOf<N>& eq = partial[c];
        const std::size_t end = std::min(n, (c + 1) * kChunkPoints);
        for (std::size_t i = c * kChunkPoints; i < end; ++i) {
            if (!valid[i] || !std::isfinite(r[i]) || !g[i].allFinite()) continue;
            const Eigen::Vector3d q = point_ref(i);
            // The ray's direction in the world is R q; |cos| of its angle to the gradient.
            if (min_incidence_cosine > 0.0 &&
                !(std::abs(g[i].dot(R * q)) >= min_incidence_cosine * g[i].norm() * q.norm())) {
                ++eq.num_oblique;
                continue;
            }
            Eigen::Matrix<double, 1, N> J;
            J.template head<6>() = point_residual_jacobian(q, R, g[i]);
            if constexpr (N == 12) {
                J.template tail<6>() = double(sweep->fractions[i]) * J.template head<6>();
            }
            const double w = kernel.weight(r[i]);
            eq.H.noalias() += w * J.transpose() * J;
            eq.b.noalias() += (w * r[i]) * J.transpose();
            eq.cost += kernel.cost(r[i]);
            eq.sum_range_sq_m2 += q.squaredNorm();
            ++eq.num_valid;
        }
    });
    for (const NormalEquationsOf<N>& eq : partial) {
        total.H += eq.H;
        total.b += eq.b;
        total.cost += eq.cost;
        total.sum_range_sq_m2 += eq.sum_range_sq_m2;
        total.num_valid += eq.num_valid;
        total.num_oblique += eq.num_oblique;
    }
    return total;
}

/// Eq. (4)'s weights, (s_kernel / sigma_j)^2.
Vector6d sweep_prior_weights(const SweepModel& sweep, const RobustKernel& kernel) {
    Vector6d w;
    w.head<3>().setConstant(std::pow(kernel.scale_m / sweep.prior_sigma_translation_m, 2));
    w.tail<3>().setConstant(std::pow(kernel.scale_m / sweep.prior_sigma_rotation_rad, 2));
    return w;
}

/// Adds Eq. (4) at `sweep_twist` and pose T to the 12-unknown sums; returns what it added to the
/// pose block of H (zero unless xi_0 follows the pose, Eq. (5)).
Matrix6d add_sweep_prior(NormalEquationsOf<12>& eq, const SweepModel& sweep,
                         const Vector6d& weights, const Eigen::Isometry3d& T,
                         const Vector6d& sweep_twist) {
    if (!sweep.T_world_previous) {
        const Vector6d d = sweep_twist - sweep.twist_prior;
        eq.H.bottomRightCorner<6, 6>().diagonal() += weights;
        eq.b.tail<6>() += weights.cwiseProduct(d);
        eq.cost += 0.5 * d.dot(weights.cwiseProduct(d));
        return Matrix6d::Zero();
    }
    // Eq. (5): d = xi - log(T_p^-1 T); its Jacobian is [-D, I] in (delta, epsilon).
    const Eigen::Isometry3d motion = sweep.T_world_previous->inverse() * T;
    const Vector6d d = sweep_twist - se3_log(motion);
    constexpr double kStep = 1e-6;
    Matrix6d D;
    for (int k = 0; k < 6; ++k) {
        Vector6d e = Vector6d::Zero();
        e[k] = kStep;
        D.col(k) = (se3_log(motion * se3_exp(e)) - se3_log(motion * se3_exp(-e))) / (2.0 * kStep);
    }
    const auto W = weights.asDiagonal();
    const Matrix6d pose_block = D.transpose() * W * D;
    eq.H.topLeftCorner<6, 6>() += pose_block;
    eq.H.topRightCorner<6, 6>() -= D.transpose() * W;
    eq.H.bottomLeftCorner<6, 6>() -= W * D;
    eq.H.bottomRightCorner<6, 6>().diagonal() += weights;
    eq.b.head<6>() -= D.transpose() * weights.cwiseProduct(d);
    eq.b.tail<6>() += weights.cwiseProduct(d);
    eq.cost += 0.5 * d.dot(weights.cwiseProduct(d));
    return pose_block;
}

}  // namespace
}  // namespace registration_solver_internal

NormalEquations build_normal_equations(const std::vector<Eigen::Vector3f>& points_sensor,
                                       const Eigen::Isometry3d& T_world_sensor,
                                       const PointResiduals& residuals,
                                       const RobustKernel& kernel) {
    return registration_solver_internal::build_equations<6>(
        points_sensor, T_world_sensor, residuals, kernel, 0.0, nullptr, Vector6d::Zero());
}

double scaled_condition_number(const Matrix6d& H, double range_m) {
    Vector6d s = Vector6d::Ones();
    if (range_m > 0.0) s.tail<3>().setConstant(1.0 / range_m);
    const Matrix6d Hs = s.asDiagonal() * H * s.asDiagonal();
    Eigen::SelfAdjointEigenSolver<Matrix6d> eig(Hs, Eigen::EigenvaluesOnly);
    const double lambda_min = eig.eigenvalues()(0);
    const double lambda_max = eig.eigenvalues()(5);
    if (!(lambda_min > 0.0) || !(lambda_max > 0.0)) {
        return std::numeric_limits<double>::infinity();
    }
    return lambda_max / lambda_min;
}

namespace registration_solver_internal {
namespace {

/// The Levenberg-Marquardt loop for N unknowns (file comment of the header).
template <int N>
RegistrationResult solve(const std::vector<Eigen::Vector3f>& points_sensor,
                         const Eigen::Isometry3d& T_world_sensor_initial,
                         const PointResiduals& residuals, const RegistrationSolverConfig& config,
                         const SweepModel* sweep) {
    using VectorN = Eigen::Matrix<double, N, 1>;
    using MatrixN = Eigen::Matrix<double, N, N>;
    RegistrationResult result;
    result.T_world_sensor = T_world_sensor_initial;
    result.T_world_sensor_solved = T_world_sensor_initial;
    result.num_points = points_sensor.size();
    Vector6d prior_weights = Vector6d::Zero();
    Vector6d twist = Vector6d::Zero();
    if constexpr (N == 12) {
        prior_weights = sweep_prior_weights(*sweep, config.kernel);
        twist = sweep->twist_prior;
    }
    result.sweep_twist = twist;
    // What the prior added to the pose block of the current iterate's H (Eq. (5)).
    Matrix6d prior_pose_block = Matrix6d::Zero();
    const auto build = [&](const Eigen::Isometry3d& T, const Vector6d& xi, Matrix6d& prior_block) {
        NormalEquationsOf<N> eq = build_equations<N>(points_sensor, T, residuals, config.kernel,
                                                     config.min_incidence_cosine, sweep, xi);
        if constexpr (N == 12) prior_block = add_sweep_prior(eq, *sweep, prior_weights, T, xi);
        return eq;
    };

    Eigen::Isometry3d T = T_world_sensor_initial;
    NormalEquationsOf<N> eq = build(T, twist, prior_pose_block);
    result.initial_cost = eq.cost;
    const auto finish = [&](RegistrationStatus status) {
        result.T_world_sensor_solved = T;
        result.final_cost = eq.cost;
        result.num_valid_points = eq.num_valid;
        result.num_oblique_points = eq.num_oblique;
        const double range_m =
            eq.num_valid > 0 ? std::sqrt(eq.sum_range_sq_m2 / double(eq.num_valid)) : 0.0;
        result.condition_number = scaled_condition_number(
            Matrix6d(eq.H.template topLeftCorner<6, 6>() - prior_pose_block), range_m);
        if (status == RegistrationStatus::kConverged &&
            !(result.condition_number <= config.max_condition_number)) {
            status = RegistrationStatus::kIllConditioned;
        }
        result.status = status;
        result.converged = status == RegistrationStatus::kConverged ||
                           status == RegistrationStatus::kIllConditioned;
        result.degenerate = status == RegistrationStatus::kTooFewPoints ||
                            status == RegistrationStatus::kIllConditioned;
        if (result.accepted()) {
            result.T_world_sensor = T;
            result.sweep_twist = twist;
        }
        return result;
    };

    double lambda = config.initial_damping;
    result.iterations = 1;
    while (true) {
        if (eq.num_valid < std::size_t(std::max(config.min_valid_points, N))) {
            return finish(RegistrationStatus::kTooFewPoints);
        }
        // Eq. (2): a damped step, retried with more damping until the cost goes down.
        MatrixN A = eq.H;
        // Marquardt's scaling by diag(H), floored so that a direction H does not constrain at
        // all (a plane's in-plane translation) gets damped too instead of an unbounded step.
        A.diagonal() +=
            lambda * eq.H.diagonal().cwiseMax(kDampingFloor * eq.H.diagonal().maxCoeff());
        const VectorN step = A.ldlt().solve(-eq.b);
        bool small = step.allFinite();
        for (int block = 0; block < N / 6; ++block) {
            small = small &&
                    step.template segment<3>(6 * block).norm() < config.converged_translation_m &&
                    step.template segment<3>(6 * block + 3).norm() < config.converged_rotation_rad;
        }
        // Below the thresholds the step is no longer worth an evaluation of every point.
        if (small && !config.try_converged_step) return finish(RegistrationStatus::kConverged);
        const Eigen::Isometry3d T_trial = T * se3_exp(step.template head<6>());
        Vector6d twist_trial = twist;
        if constexpr (N == 12) twist_trial += step.template tail<6>();
        NormalEquationsOf<N> trial;
        Matrix6d trial_prior_block = Matrix6d::Zero();
        if (step.allFinite()) trial = build(T_trial, twist_trial, trial_prior_block);
        const bool descent = step.allFinite() && trial.num_valid > 0 && trial.cost <= eq.cost;
        if (descent) {
            T = T_trial;
            twist = twist_trial;
            eq = std::move(trial);
            prior_pose_block = trial_prior_block;
            lambda = std::max(lambda * 0.1, 1e-12);
        } else {
            lambda = std::max(lambda * 10.0, 1e-6);
        }
        // A step this small is the minimum whether or not it lowered the cost (rounding).
        if (small) return finish(RegistrationStatus::kConverged);
        if (!descent && lambda > kMaxDamping) return finish(RegistrationStatus::kNoDescent);
        if (descent) {
            if (result.iterations >= config.max_iterations) {
                return finish(RegistrationStatus::kMaxIterations);
            }
            ++result.iterations;
        }
    }
}

}  // namespace
}  // namespace registration_solver_internal

RegistrationResult minimise_point_residuals(const std::vector<Eigen::Vector3f>& points_sensor,
                                            const Eigen::Isometry3d& T_world_sensor_initial,
                                            const PointResiduals& residuals,
                                            const RegistrationSolverConfig& config,
                                            const SweepModel* sweep) {
    using namespace registration_solver_internal;
    check_config(config);
    if (!sweep) return solve<6>(points_sensor, T_world_sensor_initial, residuals, config, nullptr);
    if (sweep->fractions.size() != points_sensor.size()) {
        throw DataError("registration: the sweep has " + std::to_string(sweep->fractions.size()) +
                        " point times for " + std::to_string(points_sensor.size()) + " points");
    }
    if (!(sweep->prior_sigma_translation_m > 0.0) || !(sweep->prior_sigma_rotation_rad > 0.0)) {
        throw ConfigError("registration: the sweep prior's sigmas must be positive");
    }
    return solve<12>(points_sensor, T_world_sensor_initial, residuals, config, sweep);
}

}  // namespace shine
