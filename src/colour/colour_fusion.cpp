#include "shine/colour/colour_fusion.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "shine/core/error.hpp"

namespace shine {

Eigen::Vector3d sample_bilinear(const RgbImage& image, double u, double v) {
    u = std::clamp(u, 0.0, image.width() - 1.0);
    v = std::clamp(v, 0.0, image.height() - 1.0);
    const int u0 = std::min(static_cast<int>(u), image.width() - 1);
    const int v0 = std::min(static_cast<int>(v), image.height() - 1);
    const int u1 = std::min(u0 + 1, image.width() - 1);
    const int v1 = std::min(v0 + 1, image.height() - 1);
    const double fu = u - u0, fv = v - v0;
    const auto at = [&](int x, int y) {
        const Rgb c = image.at(x, y);
        return Eigen::Vector3d(c.r, c.g, c.b);
    };
    return (1.0 - fv) * ((1.0 - fu) * at(u0, v0) + fu * at(u1, v0)) +
           fv * ((1.0 - fu) * at(u0, v1) + fu * at(u1, v1));
}

namespace colour_fusion_internal {
namespace {

/// The weight of `view`'s colour for point p_map, or 0 when the view does not see it clearly;
/// sets `colour`.
double view_weight(const CameraView& view, const MeshRaster& raster,
                   const Eigen::Isometry3d& T_camera_map, const Eigen::Vector3d& p_map,
                   const Eigen::Vector3d& n_map, const ColourFusionConfig& config,
                   Eigen::Vector3d& colour) {
    const Eigen::Vector3d p = T_camera_map * p_map;
    const double z = p.z();
    if (!(z >= config.near_m) || z > config.max_range_m) return 0.0;
    Eigen::Vector2d uv;
    if (!view.camera.project(p, uv)) return 0.0;
    double cos_angle = 1.0;
    if (!n_map.isZero(0.0)) {
        const Eigen::Vector3d to_camera_map = (view.centre_map() - p_map).normalized();
        cos_angle = std::abs(n_map.dot(to_camera_map));
        if (cos_angle < config.min_cos) return 0.0;
    }
    const int u = static_cast<int>(std::lround(uv.x()));
    const int v = static_cast<int>(std::lround(uv.y()));
    const double nearest_allowed =
        z - (config.depth_tolerance_m + config.depth_tolerance_share * z);
    const int m = std::max(0, config.edge_margin_px);
    for (int dv = -m; dv <= m; ++dv) {
        const int row = v + dv;
        if (row < 0 || row >= raster.height) continue;
        for (int du = -m; du <= m; ++du) {
            const int col = u + du;
            if (col < 0 || col >= raster.width) continue;
            if (raster.depth_m[raster.index(col, row)] < nearest_allowed) return 0.0;
        }
    }
    colour = sample_bilinear(view.image, uv.x(), uv.y());
    return cos_angle / std::max(z, 1.0);
}

}  // namespace
}  // namespace colour_fusion_internal

FusedColours fuse_colours(const std::vector<Eigen::Vector3d>& points_map,
                          const std::vector<Eigen::Vector3d>& normals_map,
                          const std::vector<CameraView>& views,
                          const std::vector<MeshRaster>& rasters,
                          const ColourFusionConfig& config) {
    using namespace colour_fusion_internal;
    if (normals_map.size() != points_map.size() || rasters.size() != views.size()) {
        throw DataError("colour fusion: " + std::to_string(points_map.size()) + " points with " +
                        std::to_string(normals_map.size()) + " normals, " +
                        std::to_string(views.size()) + " views with " +
                        std::to_string(rasters.size()) + " rasters");
    }
    std::vector<Eigen::Isometry3d> T_camera_map(views.size());
    for (std::size_t k = 0; k < views.size(); ++k)
        T_camera_map[k] = views[k].T_map_camera.inverse();
    FusedColours out;
    out.rgb.assign(points_map.size(), {0, 0, 0});
    out.weight.assign(points_map.size(), 0.0f);
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, points_map.size(), 1024),
        [&](const tbb::blocked_range<std::size_t>& r) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                Eigen::Vector3d sum = Eigen::Vector3d::Zero();
                double weight_sum = 0.0, best_weight = 0.0;
                for (std::size_t k = 0; k < views.size(); ++k) {
                    Eigen::Vector3d colour;
                    const double w = view_weight(views[k], rasters[k], T_camera_map[k],
                                                 points_map[i], normals_map[i], config, colour);
                    if (w <= 0.0) continue;
                    if (config.best_view_only) {
                        if (w > best_weight) {
                            best_weight = w;
                            sum = colour;
                        }
                    } else {
                        sum += w * colour;
                    }
                    weight_sum += w;
                }
                if (weight_sum <= 0.0) continue;
                const Eigen::Vector3d mean = config.best_view_only ? sum : sum / weight_sum;
                for (int c = 0; c < 3; ++c) {
                    out.rgb[i][c] =
                        static_cast<std::uint8_t>(std::lround(std::clamp(mean[c], 0.0, 255.0)));
                }
                out.weight[i] = static_cast<float>(weight_sum);
            }
        });
    for (const float w : out.weight) out.coloured += w > 0.0f ? 1 : 0;
    return out;
}

}  // namespace shine
