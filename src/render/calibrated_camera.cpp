#include "shine/render/calibrated_camera.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "shine/colour/mesh_raster.hpp"
#include "shine/core/error.hpp"

namespace shine {
namespace calibrated_camera_internal {

/// The intensity shown white: the 99th percentile of the finite vertex intensities (0: none).
double intensity_white_point(const std::vector<float>& intensity) {
    std::vector<float> finite;
    finite.reserve(intensity.size());
    for (const float x : intensity) {
        if (std::isfinite(x)) finite.push_back(x);
    }
    if (finite.empty()) return 0.0;
    const std::size_t k = std::min(finite.size() - 1, finite.size() * 99 / 100);
    std::nth_element(finite.begin(), finite.begin() + static_cast<std::ptrdiff_t>(k), finite.end());
    return finite[k];
}

std::uint8_t to_byte(double value) {
    return static_cast<std::uint8_t>(std::lround(std::clamp(value, 0.0, 255.0)));
}

}  // namespace calibrated_camera_internal

double srgb_to_linear(double encoded) {
    return encoded <= 0.04045 ? encoded / 12.92 : std::pow((encoded + 0.055) / 1.055, 2.4);
}

CalibratedCameraRendering render_calibrated_camera(const TriangleMesh& mesh,
                                                   const RigCamera& camera,
                                                   const Eigen::Isometry3d& T_map_camera,
                                                   double exposure_gain, double near_m) {
    using namespace calibrated_camera_internal;
    if (mesh.triangles.empty()) {
        throw DataError("the map's mesh has no triangles: nothing to render");
    }
    const bool has_rgb = !mesh.vertex_rgb.empty();
    const bool has_intensity = !mesh.vertex_intensity.empty();
    if ((has_rgb && mesh.vertex_rgb.size() != mesh.vertices.size()) ||
        (has_intensity && mesh.vertex_intensity.size() != mesh.vertices.size())) {
        throw DataError("the mesh has " + std::to_string(mesh.vertices.size()) + " vertices but " +
                        std::to_string(mesh.vertex_rgb.size()) + " colours and " +
                        std::to_string(mesh.vertex_intensity.size()) + " intensities");
    }
    CalibratedCameraRendering out;
    const double white = has_intensity ? intensity_white_point(mesh.vertex_intensity) : 0.0;
    if (has_rgb) {
        out.shading = CameraShading::kVertexColour;
    } else if (white > 0.0) {
        out.shading = CameraShading::kIntensity;
        out.intensity_white = white;
    } else {
        out.shading = CameraShading::kShadedGrey;
    }

    const MeshRaster raster = rasterize_mesh(mesh, camera, T_map_camera, near_m);
    const int width = camera.width, height = camera.height;
    const std::size_t n = static_cast<std::size_t>(width) * height;
    constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
    std::vector<float> range(n, kNaN), nx(n, kNaN), ny(n, kNaN), nz(n, kNaN);
    std::vector<float> red, green, blue, intensity;
    if (has_rgb) {
        red.assign(n, kNaN);
        green.assign(n, kNaN);
        blue.assign(n, kNaN);
    }
    if (has_intensity) intensity.assign(n, kNaN);
    out.picture.image = RgbImage(width, height, Rgb{0, 0, 0});
    out.picture.hit.assign(n, 0);
    const Eigen::Isometry3d T_camera_map = T_map_camera.inverse();
    const Eigen::Matrix3d R_map_camera = T_map_camera.linear();
    tbb::parallel_for(tbb::blocked_range<int>(0, height, 8), [&](const tbb::blocked_range<int>& r) {
        for (int v = r.begin(); v != r.end(); ++v) {
            for (int u = 0; u < width; ++u) {
                const std::size_t i = raster.index(u, v);
                const std::int32_t t = raster.triangle[i];
                if (t < 0) continue;
                // The pixel ray's hit on the triangle's plane, as render_vertex_colours takes it,
                // so that the 8-bit colours are its own.
                const Eigen::Vector3i& tri = mesh.triangles[t];
                const PixelTriangleHit hit =
                    pixel_triangle_hit(mesh, t, camera, T_camera_map, u, v);
                const Eigen::Vector3d& d = hit.ray;
                const Eigen::Vector3d& e1 = hit.edge1;
                const Eigen::Vector3d& e2 = hit.edge2;
                double distance_m = static_cast<double>(raster.depth_m[i]) / d.z();
                if (hit.crosses_plane && hit.distance_m > 0.0) distance_m = hit.distance_m;
                const std::array<double, 3>& w = hit.weights;
                range[i] = static_cast<float>(distance_m);
                // Normal in the map frame (rotated like the world frame), facing the camera.
                Eigen::Vector3d normal = e1.cross(e2);
                const double length = normal.norm();
                double cos_view = 1.0;
                if (length > 0.0) {
                    normal /= length;
                    if (normal.dot(d) > 0.0) normal = -normal;
                    cos_view = -normal.dot(d);
                    const Eigen::Vector3d normal_map = R_map_camera * normal;
                    nx[i] = static_cast<float>(normal_map.x());
                    ny[i] = static_cast<float>(normal_map.y());
                    nz[i] = static_cast<float>(normal_map.z());
                }
                double pixel_intensity = std::numeric_limits<double>::quiet_NaN();
                if (has_intensity) {
                    double sum = 0.0;
                    bool known = true;
                    for (int k = 0; k < 3; ++k) {
                        const float x = mesh.vertex_intensity[tri[k]];
                        known = known && std::isfinite(x);
                        sum += w[k] * x;
                    }
                    if (known) {
                        pixel_intensity = sum;
                        intensity[i] = static_cast<float>(sum);
                    }
                }
                Rgb pixel;
                if (has_rgb) {
                    std::array<double, 3> value{};
                    for (int k = 0; k < 3; ++k) {
                        value[k] = exposure_gain * (w[0] * mesh.vertex_rgb[tri[0]][k] +
                                                    w[1] * mesh.vertex_rgb[tri[1]][k] +
                                                    w[2] * mesh.vertex_rgb[tri[2]][k]);
                    }
                    pixel = {to_byte(value[0]), to_byte(value[1]), to_byte(value[2])};
                    const auto linear = [](double srgb) {
                        return static_cast<float>(srgb_to_linear(std::min(srgb, 255.0) / 255.0));
                    };
                    red[i] = linear(value[0]);
                    green[i] = linear(value[1]);
                    blue[i] = linear(value[2]);
                } else if (out.shading == CameraShading::kIntensity) {
                    // Black where the surface's intensity is unknown.
                    const std::uint8_t grey =
                        std::isnan(pixel_intensity)
                            ? 0
                            : to_byte(255.0 * pixel_intensity / out.intensity_white);
                    pixel = {grey, grey, grey};
                } else {
                    const std::uint8_t grey = to_byte(255.0 * (0.25 + 0.75 * std::abs(cos_view)));
                    pixel = {grey, grey, grey};
                }
                out.picture.image.set(u, v, pixel);
                out.picture.hit[i] = 1;
            }
        }
    });
    ExrImage layers(width, height);
    layers.add_channel("range.V", std::move(range));
    layers.add_channel("normal.X", std::move(nx));
    layers.add_channel("normal.Y", std::move(ny));
    layers.add_channel("normal.Z", std::move(nz));
    if (has_rgb) {
        layers.add_channel("color.R", std::move(red));
        layers.add_channel("color.G", std::move(green));
        layers.add_channel("color.B", std::move(blue));
    }
    if (has_intensity) layers.add_channel("intensity.V", std::move(intensity));
    layers.attributes["shine_units"] =
        "range: metres from the camera centre; normal: unit, world frame; color: linear sRGB "
        "(Rec. 709 primaries), 0..1; intensity: as the LiDAR gives it";
    out.layers = std::move(layers);
    return out;
}

}  // namespace shine
