#include "shine/render/pinhole_camera.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <vector>

#include "shine/core/error.hpp"

namespace shine {
namespace {

/// Comma-separated finite numbers; `bad` builds the error for an item that is not one.
template <typename Bad>
std::vector<double> parse_numbers(const std::string& text, const Bad& bad) {
    std::vector<double> v;
    std::stringstream in(text);
    std::string item;
    while (std::getline(in, item, ',')) {
        char* end = nullptr;
        const double x = std::strtod(item.c_str(), &end);
        if (item.empty() || *end != '\0' || !std::isfinite(x)) {
            throw bad("'" + item + "' is not a number");
        }
        v.push_back(x);
    }
    return v;
}

}  // namespace

Eigen::Matrix3d camera_looking_forward() {
    Eigen::Matrix3d R;
    // Columns: the optical x (right), y (down) and z (forward) axes in the sensor frame.
    R.col(0) = -Eigen::Vector3d::UnitY();
    R.col(1) = -Eigen::Vector3d::UnitZ();
    R.col(2) = Eigen::Vector3d::UnitX();
    return R;
}

Eigen::Matrix3d camera_looking_at(const Eigen::Vector3d& target_sensor,
                                  const Eigen::Vector3d& up_sensor) {
    constexpr double kMinDistanceM = 1e-6;
    constexpr double kMinSinUp = 1e-3;  // about 0.06 deg from straight up or down
    if (!(target_sensor.norm() > kMinDistanceM)) {
        throw ConfigError(
            "--camera-look-at: the target is at the sensor's position; give a point away from "
            "it");
    }
    const Eigen::Vector3d forward = target_sensor.normalized();
    const Eigen::Vector3d right = forward.cross(up_sensor.normalized());
    if (!(right.norm() > kMinSinUp)) {
        throw ConfigError(
            "--camera-look-at: the target is straight above or below the sensor, so the image's "
            "up is undefined; aim a little to the side or give --camera-rotation");
    }
    Eigen::Matrix3d R;
    R.col(0) = right.normalized();
    R.col(1) = forward.cross(R.col(0));  // down
    R.col(2) = forward;
    return R;
}

PinholeCamera parse_pinhole_camera(const std::string& text) {
    const auto bad = [&](const std::string& why) {
        return ConfigError("--camera '" + text + "': " + why +
                           " (expected fx,fy,cx,cy,w,h in pixels, e.g. 500,500,320,240,640,480)");
    };
    const std::vector<double> v = parse_numbers(text, bad);
    if (v.size() != 6) throw bad("has " + std::to_string(v.size()) + " values, not 6");
    PinholeCamera camera;
    camera.fx = v[0];
    camera.fy = v[1];
    camera.cx = v[2];
    camera.cy = v[3];
    if (!(camera.fx > 0) || !(camera.fy > 0)) throw bad("focal lengths must be positive");
    if (v[4] != std::floor(v[4]) || v[5] != std::floor(v[5]) || v[4] < 1 || v[5] < 1 ||
        v[4] > 32768 || v[5] > 32768) {
        throw bad("width and height must be whole numbers in [1, 32768]");
    }
    camera.width = static_cast<int>(v[4]);
    camera.height = static_cast<int>(v[5]);
    return camera;
}

Eigen::Vector3d parse_point3(const std::string& text, const std::string& option) {
    const auto bad = [&](const std::string& why) {
        return ConfigError(option + " '" + text + "': " + why + " (expected x,y,z in metres)");
    };
    const std::vector<double> v = parse_numbers(text, bad);
    if (v.size() != 3) throw bad("has " + std::to_string(v.size()) + " values, not 3");
    return {v[0], v[1], v[2]};
}

Eigen::Matrix3d parse_camera_rotation(const std::string& text) {
    const auto bad = [&](const std::string& why) {
        return ConfigError("--camera-rotation '" + text + "': " + why +
                           " (expected 9 numbers, a row-major rotation from the camera's optical "
                           "frame to the LiDAR's; looking forward is 0,0,1,-1,0,0,0,-1,0)");
    };
    constexpr double kTolerance = 1e-3;
    const std::vector<double> v = parse_numbers(text, bad);
    if (v.size() != 9) throw bad("has " + std::to_string(v.size()) + " values, not 9");
    Eigen::Matrix3d R;
    R << v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7], v[8];
    if (!(R.transpose() * R).isIdentity(kTolerance)) throw bad("is not orthonormal");
    if (R.determinant() < 0) throw bad("is a reflection (determinant -1), not a rotation");
    return R;
}

PixelRays camera_pixel_rays(const PinholeCamera& camera) {
    PixelRays rays;
    rays.width = camera.width;
    rays.height = camera.height;
    rays.directions_sensor.reserve(rays.num_pixels());
    for (int v = 0; v < camera.height; ++v) {
        for (int u = 0; u < camera.width; ++u) {
            const Eigen::Vector3d optical((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy,
                                          1.0);
            rays.directions_sensor.push_back((camera.R_sensor_camera * optical).normalized());
        }
    }
    return rays;
}

}  // namespace shine
