// A camera image placed in the map: what colour fusion and the photometric yardstick look
// through.
//
// Frames: T_map_camera takes points from the camera's optical frame (x right, y down, z forward;
// io/camera_rig.hpp) into the map frame, the frame a mesh's vertices are in (world position =
// mesh.origin_world_m + vertex; the world frame itself for maps near the world origin). It is
// the scan's LiDAR pose times the rig's T_lidar_camera, moved into the map frame.
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <filesystem>
#include <vector>

#include "shine/core/png_image.hpp"
#include "shine/io/camera_rig.hpp"

namespace shine {

/// One image and where its camera was.
struct CameraView {
    RigCamera camera;
    Eigen::Isometry3d T_map_camera = Eigen::Isometry3d::Identity();
    RgbImage image{1, 1};
    std::size_t scan_index = 0;  ///< the scan the image was taken with (index into the sequence)
    std::filesystem::path image_path;

    /// The camera's centre in the map frame.
    Eigen::Vector3d centre_map() const { return T_map_camera.translation(); }
};

/// T_map_camera of `camera` on a LiDAR at `T_world_lidar`, for a map frame at `origin_world_m`.
Eigen::Isometry3d camera_pose_in_map(const RigCamera& camera,
                                     const Eigen::Isometry3d& T_world_lidar,
                                     const Eigen::Vector3d& origin_world_m);

/// The images every camera of `rig` took with the scans `scan_paths` (one LiDAR pose each in
/// `T_world_lidar`), read and placed in the map frame at `origin_world_m`; scans without an
/// image from a camera are skipped. `scan_indices` (same length, or empty for 0, 1, ...) label
/// the views. Throws what load_camera_image throws (a broken image names its file), and
/// DataError for mismatched counts.
std::vector<CameraView> load_camera_views(const CameraRig& rig,
                                          const std::vector<std::filesystem::path>& scan_paths,
                                          const std::vector<Eigen::Isometry3d>& T_world_lidar,
                                          const Eigen::Vector3d& origin_world_m,
                                          const std::vector<std::size_t>& scan_indices = {});

}  // namespace shine
