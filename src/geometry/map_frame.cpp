#include "shine/geometry/map_frame.hpp"

#include <algorithm>

#include "shine/geometry/voxel_groups.hpp"

namespace shine {

Eigen::Vector3d map_origin_world_m(const Eigen::Vector3d& first_sensor_world_m) {
    return (first_sensor_world_m / 1000.0).array().round().matrix() * 1000.0;
}

Eigen::Isometry3d map_from_sensor(const Eigen::Isometry3d& T_world_sensor,
                                  const Eigen::Vector3d& origin_world_m) {
    Eigen::Isometry3d T_map_sensor = T_world_sensor;
    T_map_sensor.translation() -= origin_world_m;
    return T_map_sensor;
}

std::vector<Eigen::Vector3f> points_in_map_frame(const std::vector<Eigen::Vector3f>& points_sensor,
                                                 const Eigen::Isometry3d& T_map_sensor) {
    std::vector<Eigen::Vector3f> points_map;
    points_map.reserve(points_sensor.size());
    for (const auto& p : points_sensor) {
        points_map.push_back((T_map_sensor * p.cast<double>()).cast<float>());
    }
    return points_map;
}

Eigen::Vector3d choose_map_origin_world_m(const std::vector<double>& configured,
                                          const Eigen::Vector3d& first_sensor_world_m) {
    if (configured.size() == 3) return Eigen::Vector3d(configured[0], configured[1], configured[2]);
    return map_origin_world_m(first_sensor_world_m);
}

std::size_t crop_to_world_box(std::vector<Eigen::Vector3f>& points_map,
                              const std::vector<double>& box_world_m,
                              const Eigen::Vector3d& origin_world_m,
                              std::vector<std::uint32_t>* voxel_begin,
                              std::vector<std::uint32_t>* source_index) {
    if (box_world_m.size() != 6) return 0;
    const Eigen::Vector3d lo =
        Eigen::Vector3d(box_world_m[0], box_world_m[1], box_world_m[2]) - origin_world_m;
    const Eigen::Vector3d hi =
        Eigen::Vector3d(box_world_m[3], box_world_m[4], box_world_m[5]) - origin_world_m;
    std::vector<std::uint32_t> ungrouped;
    return filter_voxel_grouped(
        points_map, voxel_begin != nullptr ? *voxel_begin : ungrouped,
        [&](std::size_t i, std::size_t) {
            const Eigen::Vector3d q = points_map[i].cast<double>();
            return (q.array() >= lo.array()).all() && (q.array() < hi.array()).all();
        },
        source_index);
}

}  // namespace shine
