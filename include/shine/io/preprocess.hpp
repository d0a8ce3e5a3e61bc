// Per-scan preprocessing in the sensor frame: drop invalid points, range and box crop, voxel
// downsampling.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

namespace shine {

/// What to do with points whose coordinates are NaN or infinite: drop and count them (the
/// default: sensors and PCL write NaN for "no return"), or stop with a DataError
/// (`preprocess.invalid_points: error`, for data that should never hold any).
enum class InvalidPointPolicy { kError, kDrop };

/// What voxel downsampling keeps of each voxel: the point closest to its centre (`nearest`, the
/// default), or every point, grouped by voxel (`all`), for a batch mapper that draws a voxel
/// uniformly and then one of its points, so that the samples spread over space as after thinning
/// while every measured point is used (RaySet's voxel groups).
enum class VoxelPoints { kNearest, kAll };

struct PreprocessConfig {
    double min_range_m = 1.5;   ///< points closer to the sensor are dropped (ego vehicle)
    double max_range_m = 60.0;  ///< points farther away are dropped
    /// Axis-aligned crop box in the sensor frame; default: no crop.
    Eigen::Vector3d box_min_sensor_m =
        Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());
    Eigen::Vector3d box_max_sensor_m =
        Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
    double voxel_downsample_m = 0.05;  ///< keep one point per voxel of this size; 0 disables
    VoxelPoints voxel_points = VoxelPoints::kNearest;  ///< see VoxelPoints
    InvalidPointPolicy invalid_points = InvalidPointPolicy::kDrop;
};

/// Counts of what preprocessing dropped, for logs and stats.json.
struct PreprocessStats {
    std::size_t input = 0;
    std::size_t dropped_nonfinite = 0;
    std::size_t dropped_zero_range = 0;
    std::size_t dropped_range = 0;
    std::size_t dropped_box = 0;
    std::size_t dropped_downsample = 0;
    std::size_t output = 0;
    PreprocessStats& operator+=(const PreprocessStats& other);
};

/// Filters a scan. NaN or infinite points are dropped and counted in dropped_nonfinite; with
/// InvalidPointPolicy::kError the first one throws DataError naming `source` and the point's
/// index instead. Exact zero-range points (sensors' "no return") are always dropped and counted.
/// A scan with no point left (or none to begin with) gives an empty result, not an error.
/// Downsampling keeps, per voxel, the point closest to the voxel centre (deterministic, independent
/// of point order); the downsampled output is sorted by voxel key, so it is identical element by
/// element for any permutation of the input. Without downsampling the input order is kept. If
/// `stats` is given it is overwritten with this scan's counts (add them up with +=). Throws
/// ConfigError naming the key for an invalid configuration.
std::vector<Eigen::Vector3f> preprocess_scan(const std::vector<Eigen::Vector3f>& points_sensor,
                                             const PreprocessConfig& config,
                                             const std::filesystem::path& source,
                                             PreprocessStats* stats = nullptr);

/// As above, for a caller that can use voxel groups. With downsampling and VoxelPoints::kAll,
/// every kept point is returned (nothing counts as dropped_downsample), sorted by voxel key, each
/// voxel's points in a run that starts with the point the `nearest` mode keeps (then by distance
/// to the centre, ties lexicographic), and `voxel_begin` receives the index where each voxel's
/// run starts (ascending, the first 0): the runs' first points are exactly the thinned scan.
/// Otherwise the result is the plain preprocess_scan()'s and `voxel_begin` is cleared (every
/// point its own group). With `source_index`, it receives for each returned point its index in
/// `points_sensor` (the returned points are input points, unchanged).
std::vector<Eigen::Vector3f> preprocess_scan(const std::vector<Eigen::Vector3f>& points_sensor,
                                             const PreprocessConfig& config,
                                             const std::filesystem::path& source,
                                             PreprocessStats* stats,
                                             std::vector<std::uint32_t>* voxel_begin,
                                             std::vector<std::uint32_t>* source_index = nullptr);

}  // namespace shine
