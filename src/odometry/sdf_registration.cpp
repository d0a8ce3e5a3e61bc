// Scan-to-SDF registration: the SDF is the residual, its spatial gradient the Jacobian's input.
#include "shine/odometry/sdf_registration.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace shine {

void PointwiseSdfField::evaluate(const std::vector<Eigen::Vector3d>& points_world,
                                 std::vector<double>& sdf_m,
                                 std::vector<Eigen::Vector3d>& gradient_world,
                                 std::vector<std::uint8_t>& valid) const {
    const std::size_t n = points_world.size();
    sdf_m.assign(n, 0.0);
    gradient_world.assign(n, Eigen::Vector3d::Zero());
    valid.assign(n, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              valid[i] =
                                  function_(points_world[i], sdf_m[i], gradient_world[i]) ? 1 : 0;
                          }
                      });
}

RegistrationResult register_to_sdf(const std::vector<Eigen::Vector3f>& points_sensor,
                                   const Eigen::Isometry3d& T_world_sensor_initial,
                                   const SdfField& field, const SdfRegistrationConfig& config,
                                   const SweepModel* sweep) {
    const PointResiduals residuals =
        [&field](const std::vector<Eigen::Vector3d>& points_world, std::vector<double>& r,
                 std::vector<Eigen::Vector3d>& g,
                 std::vector<std::uint8_t>& valid) { field.evaluate(points_world, r, g, valid); };
    return minimise_point_residuals(points_sensor, T_world_sensor_initial, residuals, config.solver,
                                    sweep);
}

}  // namespace shine
