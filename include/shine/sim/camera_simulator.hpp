// A camera on the simulated car: images of the street's true colours (sim/scene_albedo.hpp),
// rendered by casting one ray per pixel, for testing colour fused from images onto a map.
//
// The camera is a rectified pinhole without distortion. Its optical frame is OpenCV's (x right,
// y down, z forward); pixel (u, v) has its centre at integer coordinates ((0, 0) is the top-left
// pixel's centre) and looks along normalize((u - cx) / fx, (v - cy) / fy, 1) in that frame: the
// convention of render/pinhole_camera.hpp, which the simulator cannot include (it sits above it).
// T_lidar_camera takes optical-frame coordinates to the LiDAR (sensor) frame, x forward, y left,
// z up. A pixel's colour is the albedo where its ray first meets the scene, unlit and unfiltered
// (one ray through the pixel's centre, no anti-aliasing), or kSkyColour where it meets nothing; an
// image is a pure function of the scene, the camera and the pose, identical for any thread count.
//
// In a sequence (`shine simulate --cameras`) the camera takes one image per scan from the scan's
// pose T_world_sensor * T_lidar_camera; with movers it sees them where they are at the scan's
// start (k * frame_period_s), a global shutter at the start of the LiDAR's sweep.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <filesystem>
#include <string>

#include "shine/core/png_image.hpp"
#include "shine/geometry/ray_caster.hpp"
#include "shine/sim/lidar_simulator.hpp"
#include "shine/sim/moving_scene.hpp"
#include "shine/sim/scene_albedo.hpp"

namespace shine::sim {

/// The mount of the simulated front camera on the LiDAR, like KITTI's left colour camera: 0.27 m
/// ahead of the LiDAR and 0.08 m below it (1.65 m above the road at the street's 1.73 m sensor
/// height), looking along the LiDAR's +x with the image's up = the LiDAR's +z.
Eigen::Isometry3d front_camera_mount();

/// A rectified pinhole camera on the LiDAR. Intrinsics in pixels.
struct CameraConfig {
    int width = 640;  ///< pixels
    int height = 240;
    double fx = 320.0;  ///< focal lengths: 90 x 41 deg field of view at the defaults
    double fy = 320.0;
    double cx = 319.5;  ///< principal point: the image's centre at the defaults
    double cy = 119.5;
    /// Optical frame (x right, y down, z forward) -> LiDAR frame, metres.
    Eigen::Isometry3d T_lidar_camera = front_camera_mount();
};

/// Throws ConfigError naming the field for a size outside [1, RgbImage::kMaxSide], a focal length
/// that is not positive and finite, a non-finite principal point, or a T_lidar_camera whose
/// rotation is not one (orthonormal within 1e-6, determinant +1) or whose translation is not
/// finite.
void validate(const CameraConfig& camera);

/// Unit direction of pixel (u, v)'s ray in the optical frame (u, v may be fractional).
Eigen::Vector3d camera_ray_optical(const CameraConfig& camera, double u, double v);

/// The image `camera` takes from the LiDAR pose T_world_lidar of a static street: every pixel's
/// ray cast against `caster` (built on the mesh `albedo` refers to), in parallel.
RgbImage render_camera_image(const RayCaster& caster, const SceneAlbedo& albedo,
                             const CameraConfig& camera, const Eigen::Isometry3d& T_world_lidar);

/// The same with movers, seen where they are at `time_s` (mover m's pixels: mover_albedo of its
/// kind and index m).
RgbImage render_camera_image(const MovingScene& scene, const SceneAlbedo& albedo,
                             const CameraConfig& camera, const Eigen::Isometry3d& T_world_lidar,
                             double time_s);

/// The camera's calibration as camera.yaml holds it (width, height, fx, fy, cx, cy and
/// T_lidar_camera as 12 numbers, row-major 3x4), each number written so that it reads back
/// exactly.
std::string camera_yaml(const CameraConfig& camera);

/// Where `shine simulate --cameras` puts the front camera: out_dir/cameras/front.
std::filesystem::path front_camera_dir(const std::filesystem::path& out_dir);

/// What simulate_street_cameras wrote.
struct CameraSequenceSummary {
    int num_images = 0;
    std::filesystem::path camera_dir;
    double seconds = 0.0;
};

/// Renders the street that simulate_sequence(config, out_dir) scans (the same scene, poses and
/// movers, rebuilt from `config`) with `camera` and writes
///   out_dir/cameras/front/camera.yaml    the calibration (camera_yaml)
///   out_dir/cameras/front/NNNNNN.png     scan NNNNNN's image (the stem of velodyne/NNNNNN.bin)
/// each atomically; PNGs beyond the scans (from an earlier, longer run) are removed. Throws
/// ConfigError for invalid configs and IoError when a file cannot be written.
CameraSequenceSummary simulate_street_cameras(const SimulationConfig& config,
                                              const CameraConfig& camera,
                                              const std::filesystem::path& out_dir);

/// Removes what simulate_street_cameras wrote into out_dir (camera.yaml and NNNNNN.png in
/// cameras/front, then those folders if empty), so that images of another run are never taken
/// for this one's. Returns whether anything was removed; IoError naming a file it cannot remove.
bool remove_street_cameras(const std::filesystem::path& out_dir);

}  // namespace shine::sim
