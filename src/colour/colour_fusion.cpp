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

/// Sums of an image's channels over every rectangle from its top-left corner (a summed-area
/// table), for box means in constant time. 32-bit sums: 255 * 32768^2 would overflow, but the
/// images here hold at most a few million pixels (255 * 16.8 M < 2^32).
class SummedArea {
  public:
    explicit SummedArea(const RgbImage& image)
        : width_(image.width() + 1),
          sums_(static_cast<std::size_t>(image.width() + 1) * (image.height() + 1) * 3, 0) {
        const std::vector<std::uint8_t>& px = image.pixels();
        for (int y = 0; y < image.height(); ++y) {
            std::uint32_t row[3] = {0, 0, 0};
            for (int x = 0; x < image.width(); ++x) {
                for (int c = 0; c < 3; ++c) {
                    row[c] += px[(static_cast<std::size_t>(y) * image.width() + x) * 3 + c];
                    at(x + 1, y + 1, c) = at(x + 1, y, c) + row[c];
                }
            }
        }
    }
    /// Mean colour of pixels [x0, x1] x [y0, y1] (inclusive, inside the image).
    Eigen::Vector3d mean(int x0, int y0, int x1, int y1) const {
        const double count = static_cast<double>(x1 - x0 + 1) * (y1 - y0 + 1);
        Eigen::Vector3d out;
        for (int c = 0; c < 3; ++c) {
            const std::uint32_t sum =
                get(x1 + 1, y1 + 1, c) - get(x0, y1 + 1, c) - get(x1 + 1, y0, c) + get(x0, y0, c);
            out[c] = sum / count;
        }
        return out;
    }

  private:
    std::uint32_t& at(int x, int y, int c) {
        return sums_[(static_cast<std::size_t>(y) * width_ + x) * 3 + c];
    }
    std::uint32_t get(int x, int y, int c) const {
        return sums_[(static_cast<std::size_t>(y) * width_ + x) * 3 + c];
    }
    int width_;
    std::vector<std::uint32_t> sums_;
};

namespace {

/// The weight of `view`'s colour for point p_map, or 0 when the view does not see it clearly;
/// sets `colour`.
double view_weight(const CameraView& view, const MeshRaster& raster, const SummedArea& area,
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
    // The image averaged over the point's footprint: what one colour can hold of a texture
    // finer than the surface's vertices.
    const double radius_px = 0.5 * config.footprint_m * view.camera.fx / z;
    if (radius_px >= 1.0) {
        const int r = static_cast<int>(std::lround(radius_px));
        colour = area.mean(std::max(0, u - r), std::max(0, v - r),
                           std::min(view.image.width() - 1, u + r),
                           std::min(view.image.height() - 1, v + r));
    } else {
        colour = sample_bilinear(view.image, uv.x(), uv.y());
    }
    return cos_angle / std::max(z * z, 1.0);
}

}  // namespace
}  // namespace colour_fusion_internal

ColourAccumulator::ColourAccumulator(const std::vector<Eigen::Vector3d>& points_map,
                                     const std::vector<Eigen::Vector3d>& normals_map,
                                     const ColourFusionConfig& config)
    : points_map_(points_map),
      normals_map_(normals_map),
      config_(config),
      sum_(points_map.size(), Eigen::Vector3d::Zero()),
      weight_(points_map.size(), 0.0),
      best_(points_map.size(), 0.0) {
    if (normals_map.size() != points_map.size()) {
        throw DataError("colour fusion: " + std::to_string(points_map.size()) + " points with " +
                        std::to_string(normals_map.size()) + " normals");
    }
}

void ColourAccumulator::add_view(const CameraView& view, const MeshRaster& raster) {
    using namespace colour_fusion_internal;
    if (raster.width != view.camera.width || raster.height != view.camera.height ||
        view.image.width() != view.camera.width || view.image.height() != view.camera.height) {
        throw DataError("colour fusion: the image '" + view.image_path.string() + "' (" +
                        std::to_string(view.image.width()) + "x" +
                        std::to_string(view.image.height()) + "), its raster (" +
                        std::to_string(raster.width) + "x" + std::to_string(raster.height) +
                        ") and its camera (" + std::to_string(view.camera.width) + "x" +
                        std::to_string(view.camera.height) + ") differ in size");
    }
    const SummedArea area(view.image);
    const Eigen::Isometry3d T_camera_map = view.T_map_camera.inverse();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points_map_.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              Eigen::Vector3d colour;
                              const double w =
                                  view_weight(view, raster, area, T_camera_map, points_map_[i],
                                              normals_map_[i], config_, colour);
                              if (w <= 0.0) continue;
                              if (config_.best_view_only) {
                                  if (w > best_[i]) {
                                      best_[i] = w;
                                      sum_[i] = colour;
                                  }
                              } else {
                                  sum_[i] += w * colour;
                              }
                              weight_[i] += w;
                          }
                      });
}

FusedColours ColourAccumulator::result() const {
    FusedColours out;
    out.rgb.assign(points_map_.size(), {0, 0, 0});
    out.weight.assign(points_map_.size(), 0.0f);
    for (std::size_t i = 0; i < points_map_.size(); ++i) {
        if (weight_[i] <= 0.0) continue;
        const Eigen::Vector3d mean = config_.best_view_only ? sum_[i] : sum_[i] / weight_[i];
        for (int c = 0; c < 3; ++c) {
            out.rgb[i][c] = static_cast<std::uint8_t>(std::lround(std::clamp(mean[c], 0.0, 255.0)));
        }
        // The weight's scale (1 / m^2 per view) is small: stored relative, never 0 when seen.
        out.weight[i] = static_cast<float>(std::max(weight_[i], 1e-30));
        ++out.coloured;
    }
    return out;
}

FusedColours fuse_colours(const std::vector<Eigen::Vector3d>& points_map,
                          const std::vector<Eigen::Vector3d>& normals_map,
                          const std::vector<CameraView>& views,
                          const std::vector<MeshRaster>& rasters,
                          const ColourFusionConfig& config) {
    if (rasters.size() != views.size()) {
        throw DataError("colour fusion: " + std::to_string(views.size()) + " views with " +
                        std::to_string(rasters.size()) + " rasters");
    }
    ColourAccumulator accumulator(points_map, normals_map, config);
    for (std::size_t k = 0; k < views.size(); ++k) accumulator.add_view(views[k], rasters[k]);
    return accumulator.result();
}

}  // namespace shine
