#include "shine/sim/pose_noise.hpp"

#include <cmath>
#include <random>
#include <string>

#include "shine/core/error.hpp"
#include "sim_random.hpp"

namespace shine::sim {
namespace {

using random_internal::derive_seed;
using random_internal::normal_from_bits;

/// The pose noise's stream of the simulation's seed; each scan then has its own stream below it.
/// Nested (not seed + frame like the range noise) so that no frame count reaches another stream.
constexpr std::uint64_t kPoseNoiseStream = 0x706F73655F6E6F69ULL;

void check_sigma(double value, const char* field, const char* unit) {
    if (!(std::isfinite(value) && value >= 0.0)) {
        throw ConfigError("pose noise " + std::string(field) + " = " + std::to_string(value) +
                          " must be a finite number >= 0 (" + unit +
                          "; 0 for no noise on that part of the poses)");
    }
}

}  // namespace

bool has_pose_noise(const PoseNoiseConfig& config) {
    return config.translation_sigma_m != 0.0 || config.rotation_sigma_deg != 0.0;
}

void validate(const PoseNoiseConfig& config) {
    check_sigma(config.translation_sigma_m, "translation_sigma_m", "metres per axis");
    check_sigma(config.rotation_sigma_deg, "rotation_sigma_deg", "degrees per axis");
}

PosePerturbation draw_pose_perturbation(const PoseNoiseConfig& config, int frame) {
    validate(config);
    if (frame < 0) {
        throw ConfigError("pose noise: frame = " + std::to_string(frame) + " must be >= 0");
    }
    std::mt19937_64 engine(
        derive_seed(derive_seed(config.seed, kPoseNoiseStream), static_cast<std::uint64_t>(frame)));
    const auto normal = [&engine] {
        const std::uint64_t a = engine();
        const std::uint64_t b = engine();
        return normal_from_bits(a, b);
    };
    // Always six draws, translation first, so either part's noise does not depend on the other's
    // sigma being zero.
    Eigen::Vector3d unit_translation;
    Eigen::Vector3d unit_rotation;
    for (int axis = 0; axis < 3; ++axis) unit_translation[axis] = normal();
    for (int axis = 0; axis < 3; ++axis) unit_rotation[axis] = normal();
    PosePerturbation perturbation;
    perturbation.translation_m = config.translation_sigma_m * unit_translation;
    perturbation.rotation_vector_rad = (config.rotation_sigma_deg * M_PI / 180.0) * unit_rotation;
    return perturbation;
}

Eigen::Isometry3d perturb_pose(const Eigen::Isometry3d& T_world_sensor,
                               const PosePerturbation& perturbation) {
    Eigen::Isometry3d T = T_world_sensor;
    // Skipped when zero so that a -0 coordinate stays -0 (the identity bit for bit).
    if (!perturbation.translation_m.isZero(0.0)) T.translation() += perturbation.translation_m;
    const double angle_rad = perturbation.rotation_vector_rad.norm();
    if (angle_rad > 0.0) {
        const Eigen::Matrix3d R_delta =
            Eigen::AngleAxisd(angle_rad, perturbation.rotation_vector_rad / angle_rad)
                .toRotationMatrix();
        T.linear() = R_delta * T_world_sensor.linear();
    }
    return T;
}

std::vector<Eigen::Isometry3d> add_pose_noise(const std::vector<Eigen::Isometry3d>& T_world_sensor,
                                              const PoseNoiseConfig& config) {
    validate(config);
    std::vector<Eigen::Isometry3d> noisy;
    noisy.reserve(T_world_sensor.size());
    for (std::size_t i = 0; i < T_world_sensor.size(); ++i) {
        noisy.push_back(
            perturb_pose(T_world_sensor[i], draw_pose_perturbation(config, static_cast<int>(i))));
    }
    return noisy;
}

}  // namespace shine::sim
