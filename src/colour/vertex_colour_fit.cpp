#include "shine/colour/vertex_colour_fit.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "shine/core/error.hpp"

namespace shine {
namespace vertex_colour_fit_internal {
namespace {

/// Index of (row, col), row <= col, in a symmetric 3x3 block's upper triangle.
constexpr int kBlock[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};

/// Whether a pixel within `margin` of (u, v) shows a surface nearer than `nearest_allowed_m`.
bool near_silhouette(const MeshRaster& raster, int u, int v, int margin, double nearest_allowed_m) {
    for (int dv = -margin; dv <= margin; ++dv) {
        const int row = v + dv;
        if (row < 0 || row >= raster.height) continue;
        for (int du = -margin; du <= margin; ++du) {
            const int col = u + du;
            if (col < 0 || col >= raster.width) continue;
            if (raster.depth_m[raster.index(col, row)] < nearest_allowed_m) return true;
        }
    }
    return false;
}

}  // namespace
}  // namespace vertex_colour_fit_internal

VertexColourFit::VertexColourFit(const TriangleMesh& mesh, const VertexColourFitConfig& config)
    : mesh_(mesh),
      config_(config),
      blocks_(mesh.triangles.size(), std::array<float, 6>{0, 0, 0, 0, 0, 0}),
      rhs_(mesh.vertices.size(), Eigen::Vector3d::Zero()),
      support_(mesh.vertices.size(), 0.0) {}

void VertexColourFit::add_view(const CameraView& view, const MeshRaster& raster) {
    using namespace vertex_colour_fit_internal;
    if (raster.width != view.camera.width || raster.height != view.camera.height ||
        view.image.width() != view.camera.width || view.image.height() != view.camera.height) {
        throw DataError("colour fit: the image '" + view.image_path.string() + "' (" +
                        std::to_string(view.image.width()) + "x" +
                        std::to_string(view.image.height()) + "), its raster (" +
                        std::to_string(raster.width) + "x" + std::to_string(raster.height) +
                        ") and its camera (" + std::to_string(view.camera.width) + "x" +
                        std::to_string(view.camera.height) + ") differ in size");
    }
    const Eigen::Isometry3d T_camera_map = view.T_map_camera.inverse();
    const std::vector<std::uint8_t>& pixels = view.image.pixels();
    // The pixels' barycentric coordinates in parallel (b0 < 0: pixel not used), then the sums
    // in pixel order: pixels of one triangle add to the same block, and the order keeps the
    // result independent of the thread count.
    std::vector<std::array<float, 3>> bary(raster.triangle.size(), {-1.0f, 0.0f, 0.0f});
    tbb::parallel_for(
        tbb::blocked_range<int>(0, raster.height, 4), [&](const tbb::blocked_range<int>& rows) {
            for (int v = rows.begin(); v != rows.end(); ++v) {
                for (int u = 0; u < raster.width; ++u) {
                    const std::size_t i = raster.index(u, v);
                    const std::int32_t t = raster.triangle[i];
                    if (t < 0) continue;
                    const double z = raster.depth_m[i];
                    if (z > config_.max_range_m) continue;
                    const double nearest_allowed =
                        z - (config_.depth_tolerance_m + config_.depth_tolerance_share * z);
                    if (near_silhouette(raster, u, v, std::max(0, config_.edge_margin_px),
                                        nearest_allowed)) {
                        continue;
                    }
                    const PixelTriangleHit hit =
                        pixel_triangle_hit(mesh_, t, view.camera, T_camera_map, u, v);
                    if (!hit.crosses_plane) continue;
                    bary[i] = {static_cast<float>(hit.weights[0]),
                               static_cast<float>(hit.weights[1]),
                               static_cast<float>(hit.weights[2])};
                }
            }
        });
    ViewSums sums;
    if (config_.exposure && slot_.empty()) slot_.assign(mesh_.vertices.size(), -1);
    for (std::size_t i = 0; i < bary.size(); ++i) {
        if (bary[i][0] < 0.0f) continue;
        const Eigen::Vector3i& tri = mesh_.triangles[raster.triangle[i]];
        const Eigen::Vector3d y(pixels[3 * i], pixels[3 * i + 1], pixels[3 * i + 2]);
        std::array<float, 6>& block = blocks_[raster.triangle[i]];
        for (int r = 0; r < 3; ++r) {
            const double b = bary[i][r];
            rhs_[tri[r]] += b * y;
            support_[tri[r]] += b;
            for (int c = r; c < 3; ++c) block[kBlock[r][c]] += bary[i][r] * bary[i][c];
            if (!config_.exposure) continue;
            std::int32_t& slot = slot_[tri[r]];
            if (slot < 0) {
                slot = static_cast<std::int32_t>(sums.vertex.size());
                sums.vertex.push_back(static_cast<std::uint32_t>(tri[r]));
                sums.sum.push_back({0.0f, 0.0f, 0.0f, 0.0f});
            }
            std::array<float, 4>& s = sums.sum[slot];
            for (int c = 0; c < 3; ++c) s[c] += static_cast<float>(b * y[c]);
            s[3] += static_cast<float>(b);
        }
        ++pixels_;
    }
    if (config_.exposure) {
        for (const std::uint32_t v : sums.vertex) slot_[v] = -1;
        views_.push_back(std::move(sums));
    } else {
        views_.emplace_back();
    }
}

/// The Jacobi steps' fixed parts: the diagonal of A^T A + smoothness L, the vertices that move
/// (a diagonal above 0) and the triangle corners each gathers from.
struct VertexColourFit::Jacobi {
    std::vector<double> diagonal;
    std::vector<std::uint32_t> moving;
    std::vector<std::uint32_t> first{0};  ///< moving[m]'s corners: [first[m], first[m + 1])
    std::vector<std::uint32_t> corners;   ///< 3 t + r
};

VertexColourFit::Jacobi VertexColourFit::prepare_jacobi() const {
    using namespace vertex_colour_fit_internal;
    const std::size_t n = mesh_.vertices.size();
    Jacobi system;
    std::vector<double>& diagonal = system.diagonal;
    diagonal.assign(n, 0.0);
    // The smoothness term joins vertices a pixel reached: an unseen vertex has no colour to
    // pull towards.
    const double smoothness = std::max(0.0, config_.smoothness);
    const auto smoothed = [&](int from, int to) {
        return smoothness > 0.0 && support_[from] > 0.0 && support_[to] > 0.0;
    };
    for (std::size_t t = 0; t < blocks_.size(); ++t) {
        const Eigen::Vector3i& tri = mesh_.triangles[t];
        for (int k = 0; k < 3; ++k) {
            diagonal[tri[k]] += blocks_[t][kBlock[k][k]];
            for (int j = 1; j <= 2; ++j) {
                if (smoothed(tri[k], tri[(k + j) % 3])) diagonal[tri[k]] += smoothness;
            }
        }
    }
    // Only vertices with a diagonal move. Each gathers its residual from its triangles in
    // ascending order (a vertex -> (triangle, corner) table), so the sums are taken in the order
    // a loop over the triangles would take them, and the steps run in parallel.
    std::vector<std::uint32_t>& moving = system.moving;
    std::vector<std::uint32_t>& first = system.first;
    std::vector<std::uint32_t>& corners = system.corners;
    {
        std::vector<std::uint32_t> count(n, 0);
        for (const Eigen::Vector3i& tri : mesh_.triangles) {
            for (int r = 0; r < 3; ++r) count[tri[r]] += diagonal[tri[r]] > 0.0;
        }
        std::vector<std::uint32_t> at(n, 0);
        for (std::size_t i = 0; i < n; ++i) {
            if (!(diagonal[i] > 0.0)) continue;
            at[i] = first.back();
            moving.push_back(static_cast<std::uint32_t>(i));
            first.push_back(first.back() + count[i]);
        }
        corners.resize(first.back());
        for (std::size_t t = 0; t < mesh_.triangles.size(); ++t) {
            const Eigen::Vector3i& tri = mesh_.triangles[t];
            for (int r = 0; r < 3; ++r) {
                if (diagonal[tri[r]] > 0.0)
                    corners[at[tri[r]]++] = static_cast<std::uint32_t>(3 * t + r);
            }
        }
    }
    return system;
}

std::vector<Eigen::Vector3d> VertexColourFit::solve_colours(
    const Jacobi& system, const std::vector<Eigen::Vector3d>& rhs) const {
    using namespace vertex_colour_fit_internal;
    const std::size_t n = mesh_.vertices.size();
    std::vector<Eigen::Vector3d> colour(n, Eigen::Vector3d::Zero());
    for (std::size_t i = 0; i < n; ++i) {
        if (support_[i] > 0.0) colour[i] = rhs[i] / support_[i];
    }
    const double smoothness = std::max(0.0, config_.smoothness);
    const auto smoothed = [&](int from, int to) {
        return smoothness > 0.0 && support_[from] > 0.0 && support_[to] > 0.0;
    };
    const std::vector<double>& diagonal = system.diagonal;
    const std::vector<std::uint32_t>& moving = system.moving;
    const std::vector<std::uint32_t>& first = system.first;
    const std::vector<std::uint32_t>& corners = system.corners;
    std::vector<Eigen::Vector3d> next(moving.size());
    for (int step = 0; step < config_.iterations; ++step) {
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, moving.size(), 2048),
            [&](const tbb::blocked_range<std::size_t>& range) {
                for (std::size_t m = range.begin(); m != range.end(); ++m) {
                    const std::uint32_t v = moving[m];
                    // A^T y - (A^T A + smoothness L) c at v
                    Eigen::Vector3d residual = rhs[v];
                    for (std::uint32_t e = first[m]; e < first[m + 1]; ++e) {
                        const std::size_t t = corners[e] / 3;
                        const int r = static_cast<int>(corners[e] % 3);
                        const Eigen::Vector3i& tri = mesh_.triangles[t];
                        for (int c = 0; c < 3; ++c) {
                            residual -=
                                static_cast<double>(blocks_[t][kBlock[r][c]]) * colour[tri[c]];
                        }
                        for (int j = 1; j <= 2; ++j) {
                            const int other = tri[(r + j) % 3];
                            if (smoothed(tri[r], other)) {
                                residual -= smoothness * (colour[tri[r]] - colour[other]);
                            }
                        }
                    }
                    next[m] = colour[v] + config_.relaxation * residual / diagonal[v];
                }
            });
        for (std::size_t m = 0; m < moving.size(); ++m) colour[moving[m]] = next[m];
    }
    return colour;
}

VertexColours VertexColourFit::solve() const {
    const std::size_t n = mesh_.vertices.size();
    const Jacobi system = prepare_jacobi();
    std::vector<Eigen::Vector3d> colour = solve_colours(system, rhs_);
    std::vector<double> gains(views_.size(), 1.0);
    if (config_.exposure && views_.size() >= 2) {
        for (int round = 0; round < config_.exposure_rounds; ++round) {
            // Each view's gain: its pixels' sum over the sum of the colours rendered at them,
            // A_k^T 1 . c (the ratio of the means, over all channels).
            double log_sum = 0.0;
            std::size_t fitted = 0;
            for (std::size_t k = 0; k < views_.size(); ++k) {
                double measured = 0.0, rendered = 0.0;
                for (std::size_t j = 0; j < views_[k].vertex.size(); ++j) {
                    const std::array<float, 4>& s = views_[k].sum[j];
                    measured += static_cast<double>(s[0]) + s[1] + s[2];
                    rendered += static_cast<double>(s[3]) * colour[views_[k].vertex[j]].sum();
                }
                gains[k] = measured > 0.0 && rendered > 0.0 ? measured / rendered : 0.0;
                if (gains[k] > 0.0) {
                    log_sum += std::log(gains[k]);
                    ++fitted;
                }
            }
            const double mean_gain = fitted ? std::exp(log_sum / static_cast<double>(fitted)) : 1.0;
            std::vector<Eigen::Vector3d> rhs(n, Eigen::Vector3d::Zero());
            for (std::size_t k = 0; k < views_.size(); ++k) {
                gains[k] = gains[k] > 0.0 ? gains[k] / mean_gain : 1.0;
                const double scale = 1.0 / gains[k];
                for (std::size_t j = 0; j < views_[k].vertex.size(); ++j) {
                    const std::array<float, 4>& s = views_[k].sum[j];
                    rhs[views_[k].vertex[j]] += scale * Eigen::Vector3d(s[0], s[1], s[2]);
                }
            }
            colour = solve_colours(system, rhs);
        }
    }
    VertexColours out;
    out.view_gains = std::move(gains);
    out.rgb.assign(n, {0, 0, 0});
    out.support.assign(n, 0.0f);
    for (std::size_t i = 0; i < n; ++i) {
        if (!(support_[i] > 0.0)) continue;
        for (int c = 0; c < 3; ++c) {
            out.rgb[i][c] =
                static_cast<std::uint8_t>(std::lround(std::clamp(colour[i][c], 0.0, 255.0)));
        }
        out.support[i] = static_cast<float>(support_[i]);
        ++out.coloured;
    }
    return out;
}

}  // namespace shine
