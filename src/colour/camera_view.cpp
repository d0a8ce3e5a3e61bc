#include "shine/colour/camera_view.hpp"

#include <string>

#include "shine/core/error.hpp"

namespace shine {

Eigen::Isometry3d camera_pose_in_map(const RigCamera& camera,
                                     const Eigen::Isometry3d& T_world_lidar,
                                     const Eigen::Vector3d& origin_world_m) {
    Eigen::Isometry3d T_world_camera = T_world_lidar * camera.T_lidar_camera;
    T_world_camera.translation() -= origin_world_m;
    return T_world_camera;
}

std::vector<CameraView> load_camera_views(const CameraRig& rig,
                                          const std::vector<std::filesystem::path>& scan_paths,
                                          const std::vector<Eigen::Isometry3d>& T_world_lidar,
                                          const Eigen::Vector3d& origin_world_m,
                                          const std::vector<std::size_t>& scan_indices) {
    if (T_world_lidar.size() != scan_paths.size() ||
        (!scan_indices.empty() && scan_indices.size() != scan_paths.size())) {
        throw DataError("camera views: " + std::to_string(scan_paths.size()) + " scans but " +
                        std::to_string(T_world_lidar.size()) + " poses and " +
                        std::to_string(scan_indices.size()) + " scan indices");
    }
    std::vector<CameraView> views;
    for (std::size_t s = 0; s < scan_paths.size(); ++s) {
        for (std::size_t c = 0; c < rig.cameras.size(); ++c) {
            const std::filesystem::path path = rig.image_for_scan(c, scan_paths[s]);
            if (path.empty()) continue;
            CameraView view;
            view.camera = rig.cameras[c];
            view.T_map_camera = camera_pose_in_map(view.camera, T_world_lidar[s], origin_world_m);
            view.image = load_camera_image(view.camera, path);
            view.scan_index = scan_indices.empty() ? s : scan_indices[s];
            view.image_path = path;
            views.push_back(std::move(view));
        }
    }
    return views;
}

}  // namespace shine
