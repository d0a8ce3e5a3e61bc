// Registration of a scan to a signed distance field: the pose at which the scan's points lie on
// the zero level set (the surface) of the map built so far.
//
// The residual of a point is the SDF at its world position, r_i = f(T p_i), and its gradient is
// the SDF's spatial gradient, so the Jacobian of Eq. (1) in registration_solver.hpp is analytic
// (for a neural map, the decoder's input gradient times the feature Jacobian: model's
// sdf_gradient.hpp). The robust kernel keeps points on surfaces the map has not seen (or that
// moved) from pulling the pose.
//
// This module knows nothing of the neural map: the field is an interface, evaluated for a whole
// batch of points at once so that an implementation can parallelise it. The mapper adapts its
// NeuralSdf to it; tests use analytic scenes.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <functional>
#include <vector>

#include "shine/odometry/registration_solver.hpp"

namespace shine {

/// A signed distance field in the world frame, evaluated in batches.
class SdfField {
  public:
    virtual ~SdfField() = default;

    /// For each world point: the signed distance (m), its gradient (world frame, per metre) and
    /// valid = 1 where the field is defined (0 outside the map: the point is then ignored).
    /// Outputs are resized to points_world.size(). Must be safe to call from one thread while
    /// the implementation uses others.
    virtual void evaluate(const std::vector<Eigen::Vector3d>& points_world,
                          std::vector<double>& sdf_m, std::vector<Eigen::Vector3d>& gradient_world,
                          std::vector<std::uint8_t>& valid) const = 0;
};

/// An SdfField from a function of one point (analytic scenes, tests), evaluated in parallel.
class PointwiseSdfField final : public SdfField {
  public:
    /// Returns false where the field is undefined; otherwise sets the distance and gradient.
    using Function = std::function<bool(const Eigen::Vector3d& point_world, double& sdf_m,
                                        Eigen::Vector3d& gradient_world)>;

    explicit PointwiseSdfField(Function function) : function_(std::move(function)) {}

    void evaluate(const std::vector<Eigen::Vector3d>& points_world, std::vector<double>& sdf_m,
                  std::vector<Eigen::Vector3d>& gradient_world,
                  std::vector<std::uint8_t>& valid) const override;

  private:
    Function function_;
};

/// Configuration of register_to_sdf.
struct SdfRegistrationConfig {
    /// Stopping rules and degeneracy thresholds. The kernel's scale is in metres of SDF: a point
    /// farther than a few scales from the surface is mostly ignored.
    RegistrationSolverConfig solver;
};

/// The pose T_world_sensor that puts `points_sensor` on the zero level set of `field`, by
/// Levenberg-Marquardt from `T_world_sensor_initial` (normally a constant-velocity prediction).
/// Points are used as given: thin and range-limit them first (select_registration_points). On
/// failure (result.accepted() false) the result's pose is the initial one; see
/// RegistrationResult for what is reported. With `sweep` the points are as measured during the
/// sweep, whose motion is estimated too (minimise_point_residuals). Throws ConfigError for an
/// invalid configuration.
RegistrationResult register_to_sdf(const std::vector<Eigen::Vector3f>& points_sensor,
                                   const Eigen::Isometry3d& T_world_sensor_initial,
                                   const SdfField& field, const SdfRegistrationConfig& config,
                                   const SweepModel* sweep = nullptr);

}  // namespace shine
