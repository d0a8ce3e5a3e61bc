#include "shine/mapper/scan_in_map.hpp"

#include <stdexcept>
#include <string>

#include "shine/core/error.hpp"
#include "shine/core/per_point_values.hpp"
#include "shine/geometry/map_frame.hpp"
#include "shine/geometry/voxel_groups.hpp"

namespace shine {

ScanInMap scan_in_map_frame(const Scan& scan, const MapperConfig& config, NeuralSdf& sdf,
                            bool& origin_set, PreprocessStats& stats, bool voxel_groups) {
    PreprocessStats pre;
    ScanInMap result;
    const std::size_t n = scan.points_sensor.size();
    const bool with_origins = scan.point_origin_sensor.size() == n && n > 0;
    if (!scan.intensity.empty() && scan.intensity.size() != n) {
        throw DataError("scan '" + scan.source.string() + "': " + std::to_string(n) +
                        " points but " + std::to_string(scan.intensity.size()) +
                        " intensities (Scan::intensity must be one per point, or empty)");
    }
    const bool with_intensity = !scan.intensity.empty();
    // The input index of every kept point, through preprocessing and the world crop: the
    // per-point values follow their points with it, in one place.
    const bool follow = with_origins || with_intensity;
    std::vector<std::uint32_t> source_index;
    const std::vector<Eigen::Vector3f> points_sensor = preprocess_scan(
        scan.points_sensor, config.preprocess, scan.source, &pre,
        voxel_groups ? &result.voxel_begin : nullptr, follow ? &source_index : nullptr);
    if (!origin_set) {
        sdf.origin_world_m =
            choose_map_origin_world_m(config.origin_world_m, scan.T_world_sensor.translation());
        origin_set = true;
    }
    const Eigen::Isometry3d T_map_sensor = map_from_sensor(scan.T_world_sensor, sdf.origin_world_m);
    result.origin_map = T_map_sensor.translation().cast<float>();
    result.points_map = points_in_map_frame(points_sensor, T_map_sensor);
    const std::size_t cropped =
        crop_to_world_box(result.points_map, config.crop_world_m, sdf.origin_world_m,
                          &result.voxel_begin, follow ? &source_index : nullptr);
    if (with_origins) {
        result.point_origins_map = points_in_map_frame(
            gather_per_point(scan.point_origin_sensor, n, source_index), T_map_sensor);
    }
    result.point_intensity = gather_per_point(scan.intensity, n, source_index);
    pre.dropped_box += cropped;
    pre.output -= cropped;
    stats += pre;
    return result;
}

ScanInMap voxel_leads(const ScanInMap& grouped) {
    if (grouped.voxel_begin.empty()) return grouped;
    ScanInMap leads;
    leads.origin_map = grouped.origin_map;
    const std::vector<std::uint32_t>& firsts = grouped.voxel_begin;
    const std::size_t n = grouped.points_map.size();
    leads.points_map = gather_per_point(grouped.points_map, n, firsts);
    leads.point_origins_map = gather_per_point(grouped.point_origins_map, n, firsts);
    leads.point_intensity = gather_per_point(grouped.point_intensity, n, firsts);
    return leads;
}

std::size_t drop_voxel_runs(ScanInMap& grouped, const std::vector<std::uint8_t>& drop) {
    const std::size_t runs =
        grouped.voxel_begin.empty() ? grouped.points_map.size() : grouped.voxel_begin.size();
    if (drop.size() != runs) {
        throw std::invalid_argument("drop_voxel_runs: " + std::to_string(drop.size()) +
                                    " flags for " + std::to_string(runs) + " runs");
    }
    return filter_voxel_grouped(
        grouped.points_map, grouped.voxel_begin,
        [&](std::size_t, std::size_t run) { return drop[run] == 0; }, &grouped.point_origins_map,
        &grouped.point_intensity);
}

}  // namespace shine
