#include "shine/sim/drive_trajectory.hpp"

#include <cmath>
#include <string>

#include "shine/core/error.hpp"
#include "sim_random.hpp"

namespace shine::sim {

void validate(const DriveTrajectoryConfig& c) {
    auto require = [](bool ok, const std::string& key, double value, const std::string& rule) {
        if (!ok) {
            throw ConfigError("trajectory: " + key + " = " + std::to_string(value) + " " + rule);
        }
    };
    require(c.frame_spacing_m > 0.0 && c.frame_spacing_m <= 100.0, "frame_spacing_m",
            c.frame_spacing_m, "must be in (0, 100]");
    require(c.sensor_height_m > 0.0 && c.sensor_height_m <= 100.0, "sensor_height_m",
            c.sensor_height_m, "must be in (0, 100]");
    require(c.weave_amplitude_m >= 0.0 && c.weave_amplitude_m <= 3.0, "weave_amplitude_m",
            c.weave_amplitude_m, "must be in [0, 3] (the car stays on the road)");
    require(std::abs(c.lane_offset_m) + c.weave_amplitude_m <= 4.0, "lane_offset_m",
            c.lane_offset_m, "must keep |offset| + weave amplitude within 4 m (the road)");
    require(c.weave_wavelength_m >= 5.0, "weave_wavelength_m", c.weave_wavelength_m,
            "must be >= 5");
    require(c.pitch_amplitude_deg >= 0.0 && c.pitch_amplitude_deg <= 10.0, "pitch_amplitude_deg",
            c.pitch_amplitude_deg, "must be in [0, 10]");
    require(c.roll_amplitude_deg >= 0.0 && c.roll_amplitude_deg <= 10.0, "roll_amplitude_deg",
            c.roll_amplitude_deg, "must be in [0, 10]");
}

namespace {

/// The phases of the weave and the body oscillations, drawn from the seed.
struct DrivePhases {
    double weave = 0.0;
    double pitch = 0.0;
    double roll = 0.0;
};

DrivePhases drive_phases(std::uint64_t seed) {
    random_internal::Rng rng(random_internal::derive_seed(seed, 0x7472616a));
    DrivePhases phases;
    phases.weave = rng.uniform(0.0, 2.0 * M_PI);
    phases.pitch = rng.uniform(0.0, 2.0 * M_PI);
    phases.roll = rng.uniform(0.0, 2.0 * M_PI);
    return phases;
}

Eigen::Isometry3d pose_at(const DriveTrajectoryConfig& config, const DrivePhases& phases,
                          double x) {
    // Body oscillations on shorter, incommensurate wavelengths than the weave.
    constexpr double kPitchWavelength_m = 17.0;
    constexpr double kRollWavelength_m = 11.0;
    constexpr double kDegToRad = M_PI / 180.0;
    const double k = 2.0 * M_PI / config.weave_wavelength_m;
    const double y = config.weave_amplitude_m * std::sin(k * x + phases.weave);
    const double dy_dx = config.weave_amplitude_m * k * std::cos(k * x + phases.weave);
    const double yaw = std::atan(dy_dx);  // heading follows the path tangent
    const double pitch = config.pitch_amplitude_deg * kDegToRad *
                         std::sin(2.0 * M_PI * x / kPitchWavelength_m + phases.pitch);
    const double roll = config.roll_amplitude_deg * kDegToRad *
                        std::sin(2.0 * M_PI * x / kRollWavelength_m + phases.roll);
    Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
    T_world_sensor.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    T_world_sensor.translation() =
        Eigen::Vector3d(x, config.lane_offset_m + y, config.sensor_height_m);
    return T_world_sensor;
}

}  // namespace

std::vector<Eigen::Isometry3d> make_drive_trajectory(const DriveTrajectoryConfig& config,
                                                     int num_frames, std::uint64_t seed) {
    validate(config);
    if (num_frames < 1) {
        throw ConfigError("trajectory: num_frames = " + std::to_string(num_frames) +
                          " must be >= 1");
    }
    const DrivePhases phases = drive_phases(seed);
    std::vector<Eigen::Isometry3d> poses;
    poses.reserve(num_frames);
    for (int i = 0; i < num_frames; ++i) {
        poses.push_back(pose_at(config, phases, i * config.frame_spacing_m));
    }
    return poses;
}

Eigen::Isometry3d drive_pose_at(const DriveTrajectoryConfig& config, std::uint64_t seed,
                                double x_m) {
    validate(config);
    return pose_at(config, drive_phases(seed), x_m);
}

}  // namespace shine::sim
