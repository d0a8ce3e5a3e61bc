// The points of a scan that registration uses: those within a range window, thinned to at most
// one per voxel.
//
// A LiDAR scan is dense near the sensor and sparse far away; registering all of it would spend
// most of the time on the nearby ground and weight it most. One point per voxel evens out the
// density (KISS-ICP, Vizzo et al. 2023, Sec. III-B does the same), and the range window drops the
// sensor's own vehicle and the far, noisy returns.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <vector>

namespace shine {

/// Which points of a scan (sensor frame) registration uses.
struct RegistrationPointConfig {
    double min_range_m = 1.0;   ///< closer points are dropped (the vehicle itself)
    double max_range_m = 60.0;  ///< farther points are dropped
    double voxel_size_m = 0.5;  ///< at most one point per voxel of this size; 0 keeps all
};

/// The points of `points_sensor` with min_range_m <= |p| <= max_range_m and finite coordinates,
/// keeping in each voxel (sensor frame, voxel_size_m) the first such point in input order; their
/// order is the input order. Deterministic. Throws ConfigError for a negative voxel size or an
/// empty range window.
std::vector<Eigen::Vector3f> select_registration_points(
    const std::vector<Eigen::Vector3f>& points_sensor, const RegistrationPointConfig& config);

/// The same selection as indices into `points_sensor`, ascending (to take per-point times along).
std::vector<std::size_t> select_registration_point_indices(
    const std::vector<Eigen::Vector3f>& points_sensor, const RegistrationPointConfig& config);

}  // namespace shine
