#include "shine/render/sdf_slice.hpp"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>

#include "shine/core/error.hpp"

namespace shine {

std::string SlicePlane::label() const {
    char text[64];
    std::snprintf(text, sizeof(text), "%c%.2f", "xyz"[axis], value_m);
    return text;
}

SlicePlane parse_slice_plane(const std::string& text) {
    const auto bad = [&]() {
        return ConfigError("--slice '" + text +
                           "' is not an axis-aligned plane: use x=VALUE, y=VALUE or z=VALUE "
                           "(world metres), e.g. z=1.5");
    };
    if (text.size() < 3 || text[1] != '=') throw bad();
    SlicePlane plane;
    switch (text[0]) {
        case 'x':
        case 'X':
            plane.axis = 0;
            break;
        case 'y':
        case 'Y':
            plane.axis = 1;
            break;
        case 'z':
        case 'Z':
            plane.axis = 2;
            break;
        default:
            throw bad();
    }
    const std::string value = text.substr(2);
    char* end = nullptr;
    plane.value_m = std::strtod(value.c_str(), &end);
    if (*end != '\0' || !std::isfinite(plane.value_m)) throw bad();
    return plane;
}

ExrImage slice_neural_sdf(const NeuralSdf& sdf, const SlicePlane& plane,
                          const SdfSliceConfig& config) {
    if (!(config.pixel_m >= 0.0)) {
        throw ConfigError("slice pixel size " + std::to_string(config.pixel_m) +
                          " m must be positive (or 0 for the map's leaf size)");
    }
    const double leaf_m = sdf.octree.cell_size_m(0);
    const double pixel_m = config.pixel_m > 0.0 ? config.pixel_m : leaf_m;
    const std::vector<Eigen::Vector3i> cells = sdf.octree.leaf_cells();
    if (cells.empty()) throw DataError("the map has no cells: nothing to slice");
    Eigen::Vector3i lo = cells.front(), hi = cells.front();
    for (const Eigen::Vector3i& c : cells) {
        lo = lo.cwiseMin(c);
        hi = hi.cwiseMax(c);
    }
    // The extent in the world frame: cell c covers [c, c + 1) * leaf in the map frame.
    const Eigen::Vector3d lo_world = sdf.origin_world_m + lo.cast<double>() * leaf_m;
    const Eigen::Vector3d hi_world =
        sdf.origin_world_m + (hi.cast<double>().array() + 1.0).matrix() * leaf_m;
    const int a = plane.axis;
    if (plane.value_m < lo_world[a] || plane.value_m > hi_world[a]) {
        char extent[128];
        std::snprintf(extent, sizeof(extent), "[%.2f, %.2f]", lo_world[a], hi_world[a]);
        throw DataError("slice " + plane.label() + " misses the map: its " + "xyz"[a] +
                        " extent is " + extent + " m");
    }
    // Image axes: u to the right, v down (see the header).
    const int u_axis = a == 0 ? 1 : 0;
    const int v_axis = a == 2 ? 1 : 2;
    const double extent_u = hi_world[u_axis] - lo_world[u_axis];
    const double extent_v = hi_world[v_axis] - lo_world[v_axis];
    const double width_px = std::ceil(extent_u / pixel_m);
    const double height_px = std::ceil(extent_v / pixel_m);
    if (width_px > 32768 || height_px > 32768) {
        throw DataError("slice " + plane.label() + " at " + std::to_string(pixel_m) +
                        " m pixels would be " + std::to_string(long(width_px)) + " x " +
                        std::to_string(long(height_px)) +
                        " pixels (at most 32768 a side): give a larger --pixel-m");
    }
    ExrImage image(std::max(1, int(width_px)), std::max(1, int(height_px)));
    // Pixel (0, 0)'s centre: smallest u, largest v (v points down the image).
    Eigen::Vector3d corner_world = Eigen::Vector3d::Zero();
    corner_world[a] = plane.value_m;
    corner_world[u_axis] = lo_world[u_axis] + 0.5 * pixel_m;
    corner_world[v_axis] = hi_world[v_axis] - 0.5 * pixel_m;
    std::vector<Eigen::Vector3f> points_map;
    points_map.reserve(image.num_pixels());
    for (int y = 0; y < image.height(); ++y) {
        for (int x = 0; x < image.width(); ++x) {
            Eigen::Vector3d p = corner_world;
            p[u_axis] += x * pixel_m;
            p[v_axis] -= y * pixel_m;
            points_map.push_back((p - sdf.origin_world_m).cast<float>());
        }
    }
    std::vector<float> values;
    std::vector<std::uint8_t> valid;
    sdf.query(points_map, QueryMask::kLevel0, values, valid);
    for (std::size_t i = 0; i < values.size(); ++i) {
        if (!valid[i]) values[i] = std::numeric_limits<float>::quiet_NaN();
    }
    image.add_channel("sdf.V", std::move(values));
    char text[256];
    std::snprintf(text, sizeof(text), "%.6f %.6f %.6f", corner_world.x(), corner_world.y(),
                  corner_world.z());
    image.attributes["shine_pixel00_world_m"] = text;
    std::snprintf(text, sizeof(text), "%.6f", pixel_m);
    image.attributes["shine_pixel_m"] = text;
    const char* axes[3] = {"image x = world y, image y = world -z",
                           "image x = world x, image y = world -z",
                           "image x = world x, image y = world -y"};
    image.attributes["shine_slice"] = plane.label() + ": " + axes[a];
    image.attributes["shine_units"] = "sdf: metres, positive in free space, NaN unobserved";
    return image;
}

}  // namespace shine
