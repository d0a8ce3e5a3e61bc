// The cameras of a sequence folder: calibrated pinhole cameras whose rectified images were taken
// with the LiDAR scans, read so that maps can be coloured (docs/cameras.md).
//
// Layouts recognised in a sequence directory DIR (one of them, or none: a sequence without images):
//   - KITTI-360: DIR/image_00/NNNNNN.png (the rectified images of the forward perspective camera 0,
//     one per scan DIR/velodyne/NNNNNN.bin), DIR/calibration/perspective.txt (S_rect_00, R_rect_00,
//     P_rect_00; other keys and cameras ignored) and DIR/calibration/calib_cam_to_velo.txt (12
//     numbers, row-major 3x4 [R|t], camera 0 -> LiDAR). Only camera 0 is read; image_01 and the
//     fisheye cameras are not.
//   - Generic: DIR/cameras/<name>/camera.yaml (width, height, fx, fy, cx, cy, T_lidar_camera) and
//     that camera's images DIR/cameras/<name>/<scan stem>.png; several cameras, sorted by name.
//
// KITTI-360 projects a LiDAR point p to pixel (u, v) by
//   [u w, v w, w]^T = P_rect_00 * R_rect_00 (padded to 4x4) * T_cam_to_velo^-1 * [p, 1]^T.
// With P_rect_00 = K [I | t'] (t' = K^-1 P_rect_00[:, 3], zero for camera 0), the rectified optical
// frame's point is q = R_rect_00 * T_cam_to_velo^-1 * p + t', and u = fx q_x / q_z + cx,
// v = fy q_y / q_z + cy with fx, fy, cx, cy from K. T_lidar_camera is that map's inverse, computed
// as a general 4x4 inverse: KITTI-360 stores R_rect_00 with 6 decimals, orthonormal only to about
// 1e-6, and T_camera_lidar() gives back the file's projection exactly (Isometry3d::inverse() would
// take it as an exact rotation and move pixels by up to 0.0013 px on KITTI-360's calibration).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "shine/core/png_image.hpp"

namespace shine {

/// One calibrated pinhole camera of a rig; its images are rectified (no distortion).
struct RigCamera {
    std::string name;  ///< "image_00" (KITTI-360) or the generic folder's name
    /// Pixels; pixel centres at integer coordinates, (0,0) the top-left pixel.
    double fx = 0, fy = 0, cx = 0, cy = 0;
    int width = 0, height = 0;
    /// Optical frame (x right, y down, z forward) -> LiDAR frame, metres.
    Eigen::Isometry3d T_lidar_camera = Eigen::Isometry3d::Identity();
    std::filesystem::path image_dir;
    std::filesystem::path calibration_path;  ///< the file the intrinsics came from (for messages)
    /// Pixel (u, v) of a point in the optical frame; false when z <= 0 or (u, v) falls outside
    /// [-0.5, width-0.5) x [-0.5, height-0.5). pixel_uv is left unchanged when false.
    bool project(const Eigen::Vector3d& p_camera, Eigen::Vector2d& pixel_uv) const;
    /// Unit ray of pixel (u, v) in the optical frame.
    Eigen::Vector3d pixel_ray(double u, double v) const;
    /// LiDAR frame -> optical frame: T_lidar_camera's exact (general 4x4) inverse, so that
    /// project(T_camera_lidar() * p_lidar) is the calibration files' projection of p_lidar.
    Eigen::Isometry3d T_camera_lidar() const;
};

/// The cameras of a sequence folder.
struct CameraRig {
    std::vector<RigCamera> cameras;
    std::string layout;  ///< "kitti360" or "cameras" (the generic layout)
    /// The image camera `camera` took with the scan stored at `scan_path` (same file stem, .png),
    /// or an empty path when that file does not exist. Throws std::out_of_range for a camera
    /// index >= cameras.size().
    std::filesystem::path image_for_scan(std::size_t camera,
                                         const std::filesystem::path& scan_path) const;
};

/// The cameras of sequence folder `dir`: the KITTI-360 layout or the generic one (above). nullopt
/// when `dir` has neither (a sequence without images; also for a recording file). Throws IoError
/// (a calibration file missing, unreadable or malformed: a key missing, a non-number, a wrong
/// count, a non-rotation in a KITTI-360 file), ConfigError (camera.yaml: invalid YAML, an unknown
/// or missing key, a value out of range, a non-rotation) or DataError (both layouts in one
/// folder), each naming the file, the value and the fix.
std::optional<CameraRig> find_camera_rig(const std::filesystem::path& dir);

/// Reads image `path` of `camera` as 8-bit RGB (RgbImage::read_png: IoError for a missing or
/// broken file); throws DataError naming the file when its size is not the calibration's.
RgbImage load_camera_image(const RigCamera& camera, const std::filesystem::path& path);

// --- The calibration parsers behind find_camera_rig, on text already in memory (tests and fuzz
// targets use them); `source` names the text in messages. -----------------------------------

/// What KITTI-360's perspective.txt says about camera 0's rectified image.
struct Kitti360Rectification {
    int width = 0, height = 0;              ///< S_rect_00
    double fx = 0, fy = 0, cx = 0, cy = 0;  ///< K, the left 3x3 of P_rect_00
    /// R_rect_00: camera 0's frame -> its rectified frame, as stored.
    Eigen::Matrix3d R_rect = Eigen::Matrix3d::Identity();
    Eigen::Vector3d t_rect = Eigen::Vector3d::Zero();  ///< t' = K^-1 P_rect_00[:, 3], metres
};

/// Parses the S_rect_00, R_rect_00 and P_rect_00 lines of KITTI-360's perspective.txt. Throws
/// IoError naming `source`, the key and the line for a missing or repeated key, a non-number, a
/// wrong count, a non-finite value, a size outside [1, RgbImage::kMaxSide], a P_rect_00 whose left
/// 3x3 is not [fx 0 cx; 0 fy cy; 0 0 1] with fx, fy > 0, or an R_rect_00 that is not a rotation
/// (orthonormal within 1e-3, determinant > 0).
Kitti360Rectification parse_kitti360_perspective(std::string_view text,
                                                 const std::filesystem::path& source);

/// Parses KITTI-360's calib_cam_to_velo.txt: 12 numbers, row-major 3x4 [R|t], camera 0 -> LiDAR
/// (T_velo_cam). Throws IoError naming `source` for a wrong count, a non-number, a non-finite
/// value or a non-rotation (as above).
Eigen::Isometry3d parse_kitti360_cam_to_velo(std::string_view text,
                                             const std::filesystem::path& source);

/// Camera 0 of KITTI-360 ("image_00") from its rectification and T_velo_cam (formulas above);
/// image_dir and calibration_path are left empty.
RigCamera kitti360_camera(const Kitti360Rectification& rectification,
                          const Eigen::Isometry3d& T_velo_cam);

/// Parses a generic layout's camera.yaml (docs/cameras.md): width, height (integers in
/// [1, RgbImage::kMaxSide]), fx, fy (> 0), cx, cy and T_lidar_camera (12 or 16 numbers,
/// row-major 3x4 or 4x4 with last row 0 0 0 1), all finite. Throws ConfigError naming `source`
/// and the key for invalid YAML, an unknown, repeated or missing key, a value of the wrong type or
/// out of range, or a rotation that is not orthonormal within 1e-3 with determinant +1. Sets the
/// calibration only: name, image_dir and calibration_path are left empty.
RigCamera parse_camera_yaml(std::string_view text, const std::filesystem::path& source);

}  // namespace shine
