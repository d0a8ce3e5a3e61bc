// The first step both mappers take with a scan: preprocess it in the sensor frame (preprocess.hpp),
// fix the map origin with the first scan (map_frame.hpp, or map.origin_world_m), move the points
// into the map frame and keep those inside preprocess.crop_world_m.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "shine/io/preprocess.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/mapper_config.hpp"
#include "shine/model/neural_sdf.hpp"

namespace shine {

/// A scan ready for the map: sensor position and endpoints in the map frame.
struct ScanInMap {
    Eigen::Vector3f origin_map;
    std::vector<Eigen::Vector3f> points_map;
    /// Where each voxel's run of points starts (voxel_groups.hpp); empty: one point per voxel.
    std::vector<std::uint32_t> voxel_begin;
    /// Where the sensor was when it measured each point (a deskewed scan,
    /// Scan::point_origin_sensor), in the map frame; empty: origin_map for every point.
    std::vector<Eigen::Vector3f> point_origins_map;
    /// The intensity of each point (Scan::intensity, as the sensor gives it), in step with
    /// points_map; empty when the scan has none. Nothing trains on it yet: it is kept for fusing
    /// reflectance onto the surface.
    std::vector<float> point_intensity;
};

/// Preprocesses `scan` with config.preprocess (DataError naming scan.source for invalid points,
/// per its policy, or an intensity count other than the points') and adds its counts to `stats`
/// (the world crop counts as dropped_box). The first call (origin_set false) sets
/// sdf.origin_world_m and origin_set. With `voxel_groups` (a batch mapper) and
/// preprocess.voxel_points = all, every point is kept, grouped by voxel; otherwise the scan is
/// thinned as preprocess.voxel_downsample_m says.
ScanInMap scan_in_map_frame(const Scan& scan, const MapperConfig& config, NeuralSdf& sdf,
                            bool& origin_set, PreprocessStats& stats, bool voxel_groups = false);

/// The scan as thinning keeps it, from a scan grouped by voxel: the first point of each voxel's
/// run (with its origin and intensity), which is the point preprocess_scan() keeps when it thins. A
/// scan without voxel_begin is returned as it is.
ScanInMap voxel_leads(const ScanInMap& grouped);

/// Drops the voxel runs `grouped` whose flag is nonzero (one flag per run: per point when not
/// grouped), with their points, origins and intensities; returns the number of points dropped.
/// Throws std::invalid_argument for a flag count other than the number of runs.
std::size_t drop_voxel_runs(ScanInMap& grouped, const std::vector<std::uint8_t>& drop);

}  // namespace shine
