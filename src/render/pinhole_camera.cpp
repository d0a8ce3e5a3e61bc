#include "shine/render/pinhole_camera.hpp"

#include <cmath>
#include <cstdlib>
#include <sstream>
#include <vector>

#include "shine/core/error.hpp"

namespace shine {

PinholeCamera parse_pinhole_camera(const std::string& text) {
    const auto bad = [&](const std::string& why) {
        return ConfigError("--camera '" + text + "': " + why +
                           " (expected fx,fy,cx,cy,w,h in pixels, e.g. 500,500,320,240,640,480)");
    };
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

PixelRays camera_pixel_rays(const PinholeCamera& camera) {
    PixelRays rays;
    rays.width = camera.width;
    rays.height = camera.height;
    rays.directions_sensor.reserve(rays.num_pixels());
    for (int v = 0; v < camera.height; ++v) {
        for (int u = 0; u < camera.width; ++u) {
            rays.directions_sensor.push_back(
                Eigen::Vector3d((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0)
                    .normalized());
        }
    }
    return rays;
}

}  // namespace shine
