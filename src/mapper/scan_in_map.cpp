#include "shine/mapper/scan_in_map.hpp"

#include <stdexcept>
#include <string>

#include "shine/geometry/map_frame.hpp"
#include "shine/geometry/voxel_groups.hpp"

namespace shine {

ScanInMap scan_in_map_frame(const Scan& scan, const MapperConfig& config, NeuralSdf& sdf,
                            bool& origin_set, PreprocessStats& stats, bool voxel_groups) {
    PreprocessStats pre;
    ScanInMap result;
    const bool with_origins = scan.point_origin_sensor.size() == scan.points_sensor.size() &&
                              !scan.point_origin_sensor.empty();
    std::vector<std::uint32_t> source_index;
    const std::vector<Eigen::Vector3f> points_sensor = preprocess_scan(
        scan.points_sensor, config.preprocess, scan.source, &pre,
        voxel_groups ? &result.voxel_begin : nullptr, with_origins ? &source_index : nullptr);
    if (!origin_set) {
        sdf.origin_world_m =
            choose_map_origin_world_m(config.origin_world_m, scan.T_world_sensor.translation());
        origin_set = true;
    }
    const Eigen::Isometry3d T_map_sensor = map_from_sensor(scan.T_world_sensor, sdf.origin_world_m);
    result.origin_map = T_map_sensor.translation().cast<float>();
    result.points_map = points_in_map_frame(points_sensor, T_map_sensor);
    if (with_origins) {
        std::vector<Eigen::Vector3f> origins_sensor(source_index.size());
        for (std::size_t k = 0; k < source_index.size(); ++k) {
            origins_sensor[k] = scan.point_origin_sensor[source_index[k]];
        }
        result.point_origins_map = points_in_map_frame(origins_sensor, T_map_sensor);
    }
    const std::size_t cropped =
        crop_to_world_box(result.points_map, config.crop_world_m, sdf.origin_world_m,
                          &result.voxel_begin, with_origins ? &result.point_origins_map : nullptr);
    pre.dropped_box += cropped;
    pre.output -= cropped;
    stats += pre;
    return result;
}

ScanInMap voxel_leads(const ScanInMap& grouped) {
    if (grouped.voxel_begin.empty()) return grouped;
    ScanInMap leads;
    leads.origin_map = grouped.origin_map;
    const bool with_origins = grouped.point_origins_map.size() == grouped.points_map.size();
    leads.points_map.reserve(grouped.voxel_begin.size());
    if (with_origins) leads.point_origins_map.reserve(grouped.voxel_begin.size());
    for (const std::uint32_t first : grouped.voxel_begin) {
        leads.points_map.push_back(grouped.points_map[first]);
        if (with_origins) leads.point_origins_map.push_back(grouped.point_origins_map[first]);
    }
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
        [&](std::size_t, std::size_t run) { return drop[run] == 0; }, &grouped.point_origins_map);
}

}  // namespace shine
