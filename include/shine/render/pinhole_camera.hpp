// A pinhole camera attached to the sensor, for views of a map a LiDAR image does not give.
//
// Frames: the camera sits at the sensor's origin. Its optical frame is OpenCV's (x right, y down,
// z forward, the viewing direction); pixel (u, v) looks along normalize((u - cx) / fx,
// (v - cy) / fy, 1) in that frame (pixel centres at integer coordinates, (0, 0) the top-left
// pixel). R_sensor_camera turns optical-frame directions into the sensor frame. By default the
// camera looks along the LiDAR's forward axis with the LiDAR's up as the image's up (LiDAR frame:
// x forward, y left, z up), the view a user expects from a car's or a walker's LiDAR; the
// identity would look along the LiDAR's z, straight up, where a street has no surface.
#pragma once

#include <Eigen/Core>
#include <string>

#include "shine/render/pixel_rays.hpp"

namespace shine {

/// The rotation of a camera looking along the sensor's +x with image up = sensor +z.
Eigen::Matrix3d camera_looking_forward();

/// The rotation of a camera at the sensor looking at `target_sensor` (a point in the sensor
/// frame), its image up as close to `up_sensor` as the viewing direction allows. Throws
/// ConfigError when the target is at the sensor or straight along `up_sensor` (no unique roll).
Eigen::Matrix3d camera_looking_at(const Eigen::Vector3d& target_sensor,
                                  const Eigen::Vector3d& up_sensor);

/// Intrinsics in pixels, the image size and the camera's orientation on the sensor.
struct PinholeCamera {
    double fx = 0, fy = 0, cx = 0, cy = 0;
    int width = 0, height = 0;
    /// Optical frame (x right, y down, z forward) to sensor frame.
    Eigen::Matrix3d R_sensor_camera = camera_looking_forward();
};

/// Parses "fx,fy,cx,cy,w,h" (the --camera option); the camera looks forward. Throws ConfigError
/// naming the text for a wrong count, a non-number, a non-positive focal length or a size
/// outside [1, 32768].
PinholeCamera parse_pinhole_camera(const std::string& text);

/// Parses "x,y,z" (the --camera-look-at option, `option` names it in errors). Throws ConfigError.
Eigen::Vector3d parse_point3(const std::string& text, const std::string& option);

/// Parses nine numbers, a row-major camera-to-sensor rotation (the --camera-rotation option:
/// columns are the optical frame's x right, y down, z forward in the sensor frame). Throws
/// ConfigError naming the text unless it is a rotation (orthonormal within 1e-3, determinant +1).
Eigen::Matrix3d parse_camera_rotation(const std::string& text);

/// The unit ray of every pixel, in the sensor frame (no measured ranges).
PixelRays camera_pixel_rays(const PinholeCamera& camera);

}  // namespace shine
