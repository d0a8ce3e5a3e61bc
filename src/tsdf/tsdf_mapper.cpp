#include "shine/tsdf/tsdf_mapper.hpp"

#include <chrono>
#include <cmath>

#include "shine/core/stopwatch.hpp"
#include "shine/geometry/map_frame.hpp"

namespace shine {
void TsdfMapperConfig::validate() const {
    tsdf.validate();
    mesh.validate();
}

namespace {
const TsdfConfig& validated_tsdf_config(const TsdfMapperConfig& config) {
    config.validate();
    return config.tsdf;
}
}  // namespace

TsdfMapper::TsdfMapper(const TsdfMapperConfig& config)
    : config_(config), volume_(validated_tsdf_config(config)) {}

void TsdfMapper::add_scan(const Scan& scan) {
    auto start = std::chrono::steady_clock::now();
    PreprocessStats pre;
    const std::vector<Eigen::Vector3f> points_sensor =
        preprocess_scan(scan.points_sensor, config_.preprocess, scan.source, &pre);
    stats_.preprocess += pre;
    if (!origin_set_) {
        volume_.set_origin_world_m(map_origin_world_m(scan.T_world_sensor.translation()));
        origin_set_ = true;
    }
    const Eigen::Isometry3d T_map_sensor =
        map_from_sensor(scan.T_world_sensor, volume_.origin_world_m());
    std::vector<Eigen::Vector3d> points_map;
    points_map.reserve(points_sensor.size());
    for (const auto& p : points_sensor) points_map.push_back(T_map_sensor * p.cast<double>());
    stats_.preprocess_seconds += seconds_since(start);

    start = std::chrono::steady_clock::now();
    stats_.voxel_updates += volume_.integrate(points_map, T_map_sensor.translation());
    stats_.integrate_seconds += seconds_since(start);
    stats_.points += points_map.size();
    ++stats_.frames;
}

TriangleMesh TsdfMapper::extract_mesh() const { return extract_tsdf_mesh(volume_, config_.mesh); }

}  // namespace shine
