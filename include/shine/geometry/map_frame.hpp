// The map frame: the world frame shifted by whole kilometres, chosen from the first scan, so that
// coordinates inside a map stay small whatever the poses. UTM-like translations (5e6 m) have a
// float32 spacing of 0.5 m; points therefore go from the sensor to the map frame in double and are
// rounded to float only once they are small.
#pragma once

#include <Eigen/Geometry>
#include <vector>

namespace shine {

/// The map frame's origin in the world for the first scan's sensor position: that position
/// rounded to whole kilometres.
inline Eigen::Vector3d map_origin_world_m(const Eigen::Vector3d& first_sensor_world_m) {
    return (first_sensor_world_m / 1000.0).array().round().matrix() * 1000.0;
}

/// The sensor-to-map transform of a sensor-to-world pose.
inline Eigen::Isometry3d map_from_sensor(const Eigen::Isometry3d& T_world_sensor,
                                         const Eigen::Vector3d& origin_world_m) {
    Eigen::Isometry3d T_map_sensor = T_world_sensor;
    T_map_sensor.translation() -= origin_world_m;
    return T_map_sensor;
}

/// Sensor-frame points in the map frame, transformed in double and rounded to float.
inline std::vector<Eigen::Vector3f> points_in_map_frame(
    const std::vector<Eigen::Vector3f>& points_sensor, const Eigen::Isometry3d& T_map_sensor) {
    std::vector<Eigen::Vector3f> points_map;
    points_map.reserve(points_sensor.size());
    for (const auto& p : points_sensor) {
        points_map.push_back((T_map_sensor * p.cast<double>()).cast<float>());
    }
    return points_map;
}

}  // namespace shine
