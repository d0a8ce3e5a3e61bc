// The map frame: the world frame shifted by whole kilometres, chosen from the first scan, so that
// coordinates inside a map stay small whatever the poses. UTM-like translations (5e6 m) have a
// float32 spacing of 0.5 m; points therefore go from the sensor to the map frame in double and are
// rounded to float only once they are small.
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace shine {

/// The map frame's origin in the world for the first scan's sensor position: that position
/// rounded to whole kilometres.
Eigen::Vector3d map_origin_world_m(const Eigen::Vector3d& first_sensor_world_m);

/// The sensor-to-map transform of a sensor-to-world pose.
Eigen::Isometry3d map_from_sensor(const Eigen::Isometry3d& T_world_sensor,
                                  const Eigen::Vector3d& origin_world_m);

/// Sensor-frame points in the map frame, transformed in double and rounded to float.
std::vector<Eigen::Vector3f> points_in_map_frame(const std::vector<Eigen::Vector3f>& points_sensor,
                                                 const Eigen::Isometry3d& T_map_sensor);

/// The map origin a run uses: `configured` ([E, N, U] m) when it has three values, else
/// map_origin_world_m() of the first scan's position.
Eigen::Vector3d choose_map_origin_world_m(const std::vector<double>& configured,
                                          const Eigen::Vector3d& first_sensor_world_m);

/// Removes the map-frame points outside the world box `box_world_m` ([xmin, ymin, zmin, xmax,
/// ymax, zmax]; empty: keeps all) and returns how many were removed. With `voxel_begin`, the
/// points are grouped by voxel (voxel_groups.hpp) and the groups are rewritten for what is kept.
/// `source_index` (each point's index in the scan it came from, or empty) keeps those of the
/// kept points, with which the scan's other per-point values follow (per_point_values.hpp).
std::size_t crop_to_world_box(std::vector<Eigen::Vector3f>& points_map,
                              const std::vector<double>& box_world_m,
                              const Eigen::Vector3d& origin_world_m,
                              std::vector<std::uint32_t>* voxel_begin = nullptr,
                              std::vector<std::uint32_t>* source_index = nullptr);

}  // namespace shine
