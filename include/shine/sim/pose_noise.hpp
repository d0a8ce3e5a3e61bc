// Noisy poses for pose refinement: every true pose T_world_sensor moved by its own random
// perturbation, so that a refiner can start from the noisy poses and be scored against the true
// ones it never saw (`shine simulate --pose-noise-m S --pose-noise-deg A`).
//
// Scan k's perturbation is a translation δt_k [m] and a rotation vector δφ_k [rad], each axis an
// independent Gaussian, independent between scans and between axes:
//
//   δt_k ~ N(0, S² I₃),   δφ_k ~ N(0, (A π/180)² I₃),
//   R_noisy = exp([δφ_k]×) R_true,   t_noisy = t_true + δt_k.
//
// As a left multiplication, T_noisy = Δ_k T_true with Δ_k = [exp([δφ_k]×) | t_true + δt_k −
// exp([δφ_k]×) t_true]: the rotation is about world axes through the sensor's own position, not
// through the world origin. Rotating about the origin would move the sensor by ~|δφ| |t_true| on
// top of δt (26 km for 0.3° at UTM-like coordinates of 5e6 m), so the translation noise would no
// longer be S per axis wherever the drive is.
//
// Every scan is perturbed, the first one too: there is no anchor scan, so a refined trajectory is
// scored after alignment (`shine eval-poses`, whose default is an SE(3) alignment).
//
// Scan k's draw depends on (seed, k) only: the noise of a scan is the same for any number of scans,
// and it comes from its own stream, so the scans simulated with the same seed do not change.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

namespace shine::sim {

/// The noise added to the poses; both sigmas 0 (the default) leaves them as they are.
struct PoseNoiseConfig {
    double translation_sigma_m = 0.0;  ///< standard deviation of each axis of δt, m
    double rotation_sigma_deg = 0.0;   ///< standard deviation of each axis of δφ, deg
    std::uint64_t seed = 1;            ///< the simulation's seed; the noise has its own stream
};

/// True when either sigma is non-zero.
bool has_pose_noise(const PoseNoiseConfig& config);

/// Throws ConfigError naming the field for a negative or non-finite sigma.
void validate(const PoseNoiseConfig& config);

/// One scan's perturbation: translation δt [m] and rotation vector δφ [rad], world axes.
struct PosePerturbation {
    Eigen::Vector3d translation_m = Eigen::Vector3d::Zero();
    Eigen::Vector3d rotation_vector_rad = Eigen::Vector3d::Zero();
};

/// The perturbation of scan `frame` (>= 0) drawn from (config.seed, frame). Both sigmas 0 give
/// zero vectors. Throws ConfigError as validate() does.
PosePerturbation draw_pose_perturbation(const PoseNoiseConfig& config, int frame);

/// T_world_sensor with `perturbation` applied: R = exp([δφ]×) R, t = t + δt (see the top of this
/// file). A zero perturbation returns the pose bit for bit.
Eigen::Isometry3d perturb_pose(const Eigen::Isometry3d& T_world_sensor,
                               const PosePerturbation& perturbation);

/// Every pose perturbed by its scan's draw (pose i is scan i). Throws ConfigError as validate().
std::vector<Eigen::Isometry3d> add_pose_noise(const std::vector<Eigen::Isometry3d>& T_world_sensor,
                                              const PoseNoiseConfig& config);

}  // namespace shine::sim
