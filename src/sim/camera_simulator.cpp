#include "shine/sim/camera_simulator.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <regex>
#include <sstream>
#include <system_error>
#include <vector>

#include "sequence_files.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"

namespace shine::sim {
namespace camera_internal {

/// A number that reads back exactly, as short as that allows; integers keep a ".0" so that YAML
/// reads them as floats.
std::string exact_number(double value) {
    value += 0.0;  // -0 -> 0
    char buffer[64];
    for (const int digits : {15, 16, 17}) {
        std::snprintf(buffer, sizeof(buffer), "%.*g", digits, value);
        if (std::strtod(buffer, nullptr) == value) break;
    }
    std::string text = buffer;
    if (text.find_first_of(".eEn") == std::string::npos) text += ".0";
    return text;
}

/// The image of `camera` at T_world_lidar; `cast(origin, direction)` gives a pixel's colour.
template <class ColourOfRay>
RgbImage render(const CameraConfig& camera, const Eigen::Isometry3d& T_world_lidar,
                const ColourOfRay& colour_of_ray) {
    validate(camera);
    const Eigen::Isometry3d T_world_camera = T_world_lidar * camera.T_lidar_camera;
    const Eigen::Vector3d origin_world = T_world_camera.translation();
    const Eigen::Matrix3d R_world_camera = T_world_camera.linear();
    RgbImage image(camera.width, camera.height, kSkyColour);
    // Each pixel is written by exactly one task and depends on nothing else: the image is the
    // same for any schedule.
    tbb::parallel_for(tbb::blocked_range<int>(0, camera.height, 4),
                      [&](const tbb::blocked_range<int>& rows) {
                          for (int v = rows.begin(); v != rows.end(); ++v) {
                              for (int u = 0; u < camera.width; ++u) {
                                  const Eigen::Vector3d direction_world =
                                      R_world_camera * camera_ray_optical(camera, u, v);
                                  image.set(u, v, colour_of_ray(origin_world, direction_world));
                              }
                          }
                      });
    return image;
}

}  // namespace camera_internal

using namespace camera_internal;

Eigen::Isometry3d front_camera_mount() {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    // Columns: the optical x (right), y (down) and z (forward) axes in the LiDAR frame.
    T.linear().col(0) = -Eigen::Vector3d::UnitY();
    T.linear().col(1) = -Eigen::Vector3d::UnitZ();
    T.linear().col(2) = Eigen::Vector3d::UnitX();
    T.translation() = Eigen::Vector3d(0.27, 0.0, -0.08);
    return T;
}

void validate(const CameraConfig& c) {
    auto require = [](bool ok, const std::string& key, double value, const std::string& rule) {
        if (!ok) throw ConfigError("camera: " + key + " = " + std::to_string(value) + " " + rule);
    };
    require(c.width >= 1 && c.width <= RgbImage::kMaxSide, "width", c.width,
            "must be in [1, " + std::to_string(RgbImage::kMaxSide) + "] pixels");
    require(c.height >= 1 && c.height <= RgbImage::kMaxSide, "height", c.height,
            "must be in [1, " + std::to_string(RgbImage::kMaxSide) + "] pixels");
    require(std::isfinite(c.fx) && c.fx > 0.0, "fx", c.fx, "must be a positive number of pixels");
    require(std::isfinite(c.fy) && c.fy > 0.0, "fy", c.fy, "must be a positive number of pixels");
    require(std::isfinite(c.cx), "cx", c.cx, "must be finite");
    require(std::isfinite(c.cy), "cy", c.cy, "must be finite");
    const Eigen::Matrix3d R = c.T_lidar_camera.linear();
    const double orthonormal_error = (R.transpose() * R - Eigen::Matrix3d::Identity()).norm();
    if (!(orthonormal_error < 1e-6 && R.determinant() > 0.0) ||
        !c.T_lidar_camera.translation().allFinite()) {
        throw ConfigError(
            "camera: T_lidar_camera must be a rotation (orthonormal, determinant +1) and a finite "
            "translation; got |R^T R - I| = " +
            std::to_string(orthonormal_error) + ", det(R) = " + std::to_string(R.determinant()));
    }
}

Eigen::Vector3d camera_ray_optical(const CameraConfig& camera, double u, double v) {
    return Eigen::Vector3d((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0)
        .normalized();
}

RgbImage render_camera_image(const RayCaster& caster, const SceneAlbedo& albedo,
                             const CameraConfig& camera, const Eigen::Isometry3d& T_world_lidar) {
    return render(camera, T_world_lidar,
                  [&](const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) {
                      const RayHit hit = caster.cast(origin, direction);
                      if (!hit.hit()) return kSkyColour;
                      return albedo.at(hit.triangle_id, origin + hit.distance_m * direction);
                  });
}

RgbImage render_camera_image(const MovingScene& scene, const SceneAlbedo& albedo,
                             const CameraConfig& camera, const Eigen::Isometry3d& T_world_lidar,
                             double time_s) {
    const auto num_static = static_cast<std::int32_t>(scene.num_static_triangles());
    const auto& movers = scene.tracks().movers;
    return render(camera, T_world_lidar,
                  [&](const Eigen::Vector3d& origin, const Eigen::Vector3d& direction) {
                      const RayHit hit = scene.cast(
                          origin, direction, 0.0, std::numeric_limits<double>::infinity(), time_s);
                      if (!hit.hit()) return kSkyColour;
                      if (hit.triangle_id >= num_static) {
                          const auto m = static_cast<std::size_t>(hit.triangle_id - num_static);
                          return mover_albedo(movers[m].kind, m);
                      }
                      return albedo.at(hit.triangle_id, origin + hit.distance_m * direction);
                  });
}

std::string camera_yaml(const CameraConfig& camera) {
    validate(camera);
    std::ostringstream out;
    out << "# The front camera of a simulated sequence (`shine simulate --cameras`): a rectified\n"
        << "# pinhole without distortion; pixel centres at integer coordinates, (0, 0) the "
           "top-left\n"
        << "# pixel's centre; one image per scan, cameras/front/<scan stem>.png.\n"
        << "width: " << camera.width << "          # pixels\n"
        << "height: " << camera.height << "\n"
        << "fx: " << exact_number(camera.fx) << "           # pixels\n"
        << "fy: " << exact_number(camera.fy) << "\n"
        << "cx: " << exact_number(camera.cx) << "\n"
        << "cy: " << exact_number(camera.cy) << "\n"
        << "# optical frame (x right, y down, z forward) -> LiDAR frame, row-major 3x4, metres\n"
        << "T_lidar_camera: [";
    const Eigen::Matrix<double, 3, 4> T = camera.T_lidar_camera.matrix().topRows<3>();
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) {
            out << exact_number(T(r, c)) << (r == 2 && c == 3 ? "]\n" : ", ");
        }
    }
    return out.str();
}

std::filesystem::path front_camera_dir(const std::filesystem::path& out_dir) {
    return out_dir / "cameras" / "front";
}

CameraSequenceSummary simulate_street_cameras(const SimulationConfig& config,
                                              const CameraConfig& camera,
                                              const std::filesystem::path& out_dir) {
    validate(config);
    validate(camera);
    const auto start = std::chrono::steady_clock::now();
    const StreetSceneConfig scene_config = simulation_scene_config(config);
    const StreetScene scene = make_street_scene(scene_config);
    const RayCaster caster(scene.mesh);
    const SceneAlbedo albedo(scene, scene_config);
    const std::vector<Eigen::Isometry3d> poses = simulation_poses(config);
    const MoverTracks movers = simulation_movers(config);
    const MovingScene moving(caster, movers);

    CameraSequenceSummary summary;
    summary.camera_dir = front_camera_dir(out_dir);
    ensure_directory(summary.camera_dir);
    sequence_internal::remove_stale_scans(summary.camera_dir, config.num_frames, "png");
    write_stream_atomically(summary.camera_dir / "camera.yaml",
                            [&](std::ostream& out) { out << camera_yaml(camera); });
    Progress progress("camera", poses.size(), config.show_progress);
    for (std::size_t k = 0; k < poses.size(); ++k) {
        const RgbImage image =
            movers.movers.empty()
                ? render_camera_image(caster, albedo, camera, poses[k])
                : render_camera_image(moving, albedo, camera, poses[k],
                                      static_cast<double>(k) * movers.frame_period_s);
        std::string stem = sequence_internal::format_frame(static_cast<int>(k));
        stem.resize(stem.size() - 4);  // NNNNNN.bin -> NNNNNN
        image.write_png(summary.camera_dir / (stem + ".png"));
        progress.update(k + 1, "images");
    }
    progress.finish(std::to_string(poses.size()) + " images");
    summary.num_images = static_cast<int>(poses.size());
    summary.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return summary;
}

bool remove_street_cameras(const std::filesystem::path& out_dir) {
    namespace fs = std::filesystem;
    const fs::path dir = front_camera_dir(out_dir);
    if (!fs::is_directory(dir)) return false;
    bool removed = false;
    const std::regex image_name(R"(\d{6}\.png)");
    std::error_code ec;
    std::vector<fs::path> ours;
    for (const auto& entry : fs::directory_iterator(dir)) {
        const std::string name = entry.path().filename().string();
        if (name == "camera.yaml" || std::regex_match(name, image_name)) ours.push_back(entry);
    }
    for (const fs::path& path : ours) {
        if (!fs::remove(path, ec) && ec) {
            throw IoError("cannot remove " + path.string() +
                          " left by an earlier run with --cameras: " + ec.message() +
                          "; delete it or choose another output directory");
        }
        removed = true;
    }
    // Folders are removed only when empty (fs::remove refuses others): files of the user's stay.
    for (const fs::path& folder : {dir, dir.parent_path()}) {
        if (fs::is_directory(folder) && fs::is_empty(folder)) fs::remove(folder, ec);
    }
    return removed;
}

}  // namespace shine::sim
