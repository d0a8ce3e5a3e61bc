// A pinhole camera attached to the sensor, for views of a map a LiDAR image does not give.
//
// Frame: the camera sits at the sensor's origin with the sensor's axes relabelled as an optical
// frame: z forward (the image's viewing direction) = sensor z, x right = sensor x, y down =
// sensor y; so pixel (u, v) looks along normalize((u - cx) / fx, (v - cy) / fy, 1) in the sensor
// frame (OpenCV's convention: pixel centres at integer coordinates, (0, 0) the top-left pixel).
// To look along a LiDAR's forward axis (sensor x), rotate the pose, not the camera.
#pragma once

#include <string>

#include "shine/render/pixel_rays.hpp"

namespace shine {

/// Intrinsics in pixels and the image size.
struct PinholeCamera {
    double fx = 0, fy = 0, cx = 0, cy = 0;
    int width = 0, height = 0;
};

/// Parses "fx,fy,cx,cy,w,h" (the --camera option). Throws ConfigError naming the text for a
/// wrong count, a non-number, a non-positive focal length or a size outside [1, 32768].
PinholeCamera parse_pinhole_camera(const std::string& text);

/// The unit ray of every pixel, in the sensor frame (no measured ranges).
PixelRays camera_pixel_rays(const PinholeCamera& camera);

}  // namespace shine
