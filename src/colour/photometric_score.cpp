#include "shine/colour/photometric_score.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
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

ColourRendering render_vertex_colours(const TriangleMesh& mesh,
                                      const std::vector<std::array<std::uint8_t, 3>>& vertex_rgb,
                                      const RigCamera& camera,
                                      const Eigen::Isometry3d& T_map_camera, double exposure_gain) {
    if (vertex_rgb.size() != mesh.vertices.size()) {
        throw DataError("render_vertex_colours: " + std::to_string(vertex_rgb.size()) +
                        " colours for " + std::to_string(mesh.vertices.size()) + " vertices");
    }
    const MeshRaster raster = rasterize_mesh(mesh, camera, T_map_camera);
    ColourRendering out;
    out.image = RgbImage(camera.width, camera.height, Rgb{0, 0, 0});
    out.hit.assign(static_cast<std::size_t>(camera.width) * camera.height, 0);
    const Eigen::Isometry3d T_camera_map = T_map_camera.inverse();
    tbb::parallel_for(
        tbb::blocked_range<int>(0, camera.height, 8), [&](const tbb::blocked_range<int>& r) {
            for (int v = r.begin(); v != r.end(); ++v) {
                for (int u = 0; u < camera.width; ++u) {
                    const std::int32_t t = raster.triangle[raster.index(u, v)];
                    if (t < 0) continue;
                    const Eigen::Vector3i& tri = mesh.triangles[t];
                    const auto [w0, w1, w2] =
                        pixel_triangle_hit(mesh, t, camera, T_camera_map, u, v).weights;
                    Rgb pixel;
                    std::uint8_t* channels[3] = {&pixel.r, &pixel.g, &pixel.b};
                    for (int k = 0; k < 3; ++k) {
                        const double value = exposure_gain * (w0 * vertex_rgb[tri[0]][k] +
                                                              w1 * vertex_rgb[tri[1]][k] +
                                                              w2 * vertex_rgb[tri[2]][k]);
                        *channels[k] =
                            static_cast<std::uint8_t>(std::lround(std::clamp(value, 0.0, 255.0)));
                    }
                    out.image.set(u, v, pixel);
                    out.hit[raster.index(u, v)] = 1;
                }
            }
        });
    return out;
}

double psnr_from_mse(double mse) {
    if (!(mse > 0.0)) return std::numeric_limits<double>::infinity();
    return 10.0 * std::log10(255.0 * 255.0 / mse);
}

PhotometricScore score_rendering(const ColourRendering& rendering, const RgbImage& image) {
    if (rendering.image.width() != image.width() || rendering.image.height() != image.height()) {
        throw DataError("score_rendering: a " + std::to_string(rendering.image.width()) + "x" +
                        std::to_string(rendering.image.height()) + " rendering against a " +
                        std::to_string(image.width()) + "x" + std::to_string(image.height()) +
                        " image");
    }
    PhotometricScore score;
    double squared = 0.0;
    const std::vector<std::uint8_t>& a = rendering.image.pixels();
    const std::vector<std::uint8_t>& b = image.pixels();
    for (std::size_t i = 0; i < rendering.hit.size(); ++i) {
        if (!rendering.hit[i]) continue;
        ++score.hit_pixels;
        for (int c = 0; c < 3; ++c) {
            const double e = static_cast<double>(a[3 * i + c]) - static_cast<double>(b[3 * i + c]);
            squared += e * e;
        }
    }
    score.hit_share =
        rendering.hit.empty() ? 0.0 : static_cast<double>(score.hit_pixels) / rendering.hit.size();
    if (score.hit_pixels > 0) {
        score.mse = squared / (3.0 * static_cast<double>(score.hit_pixels));
        score.psnr_db = psnr_from_mse(score.mse);
    }
    return score;
}

std::vector<std::array<std::uint8_t, 3>> nearest_camera_colours(
    const TriangleMesh& mesh, const std::vector<CameraView>& views) {
    std::vector<Eigen::Isometry3d> T_camera_map(views.size());
    for (std::size_t k = 0; k < views.size(); ++k)
        T_camera_map[k] = views[k].T_map_camera.inverse();
    std::vector<std::array<std::uint8_t, 3>> rgb(mesh.vertices.size(), {0, 0, 0});
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rgb.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              const Eigen::Vector3d p = mesh.vertices[i].cast<double>();
                              double best = std::numeric_limits<double>::infinity();
                              for (std::size_t k = 0; k < views.size(); ++k) {
                                  const double d = (views[k].centre_map() - p).squaredNorm();
                                  if (d >= best) continue;
                                  Eigen::Vector2d uv;
                                  if (!views[k].camera.project(T_camera_map[k] * p, uv)) continue;
                                  best = d;
                                  const Eigen::Vector3d c =
                                      sample_bilinear(views[k].image, uv.x(), uv.y());
                                  for (int ch = 0; ch < 3; ++ch) {
                                      rgb[i][ch] = static_cast<std::uint8_t>(std::lround(c[ch]));
                                  }
                              }
                          }
                      });
    return rgb;
}

}  // namespace shine

namespace shine {

HeldoutColourScores score_heldout_images(const TriangleMesh& mesh,
                                         const std::vector<CameraView>& mapped,
                                         const std::vector<CameraView>& heldout,
                                         const std::vector<double>& heldout_gains) {
    if (mesh.vertex_rgb.size() != mesh.vertices.size()) {
        throw DataError("held-out colour score: the mesh has no vertex colours");
    }
    if (!heldout_gains.empty() && heldout_gains.size() != heldout.size()) {
        throw DataError("held-out colour score: " + std::to_string(heldout_gains.size()) +
                        " exposure gains for " + std::to_string(heldout.size()) + " views");
    }
    const std::vector<std::array<std::uint8_t, 3>> baseline = nearest_camera_colours(mesh, mapped);
    HeldoutColourScores out;
    double map_squared = 0.0, baseline_squared = 0.0;
    std::size_t hits = 0, pixels = 0;
    for (std::size_t h = 0; h < heldout.size(); ++h) {
        const CameraView& view = heldout[h];
        const double gain = heldout_gains.empty() ? 1.0 : heldout_gains[h];
        HeldoutImageScore frame;
        frame.scan_index = view.scan_index;
        frame.image_path = view.image_path;
        frame.map = score_rendering(
            render_vertex_colours(mesh, mesh.vertex_rgb, view.camera, view.T_map_camera, gain),
            view.image);
        frame.baseline = score_rendering(
            render_vertex_colours(mesh, baseline, view.camera, view.T_map_camera), view.image);
        map_squared += frame.map.mse * 3.0 * static_cast<double>(frame.map.hit_pixels);
        baseline_squared +=
            frame.baseline.mse * 3.0 * static_cast<double>(frame.baseline.hit_pixels);
        hits += frame.map.hit_pixels;
        pixels += static_cast<std::size_t>(view.camera.width) * view.camera.height;
        out.frames.push_back(frame);
    }
    if (hits > 0) {
        out.map_psnr_db = psnr_from_mse(map_squared / (3.0 * static_cast<double>(hits)));
        out.baseline_psnr_db = psnr_from_mse(baseline_squared / (3.0 * static_cast<double>(hits)));
    }
    out.hit_share = pixels ? static_cast<double>(hits) / static_cast<double>(pixels) : 0.0;
    return out;
}

}  // namespace shine
