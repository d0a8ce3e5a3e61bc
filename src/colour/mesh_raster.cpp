#include "shine/colour/mesh_raster.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace shine {
namespace mesh_raster_internal {
namespace {

constexpr int kBandRows = 8;  ///< rows per band of the parallel rasteriser

/// A vertex projected into the image: pixel coordinates and 1/z (0: nearer than near_m).
struct ScreenVertex {
    double u = 0, v = 0, inv_z = 0;
};

/// A triangle's corners projected into the image: pixel coordinates and 1/z.
struct ScreenTriangle {
    double u[3], v[3], inv_z[3];
    int row_min, row_max, col_min, col_max;  ///< pixels whose centres may lie inside
};

/// The triangle `tri` in the image, or false when a corner is nearer than near_m or no pixel
/// centre can lie inside it.
bool screen_triangle(const Eigen::Vector3i& tri, const std::vector<ScreenVertex>& screen,
                     const RigCamera& camera, ScreenTriangle& out) {
    double u_min = std::numeric_limits<double>::infinity(), u_max = -u_min;
    double v_min = u_min, v_max = -u_min;
    for (int k = 0; k < 3; ++k) {
        const ScreenVertex& s = screen[tri[k]];
        if (!(s.inv_z > 0.0)) return false;
        out.u[k] = s.u;
        out.v[k] = s.v;
        out.inv_z[k] = s.inv_z;
        u_min = std::min(u_min, s.u);
        u_max = std::max(u_max, s.u);
        v_min = std::min(v_min, s.v);
        v_max = std::max(v_max, s.v);
    }
    if (u_max < 0.0 || v_max < 0.0 || u_min > camera.width - 1.0 || v_min > camera.height - 1.0) {
        return false;
    }
    out.col_min = static_cast<int>(std::max(0.0, std::ceil(u_min)));
    out.col_max = static_cast<int>(std::min(camera.width - 1.0, std::floor(u_max)));
    out.row_min = static_cast<int>(std::max(0.0, std::ceil(v_min)));
    out.row_max = static_cast<int>(std::min(camera.height - 1.0, std::floor(v_max)));
    return out.col_min <= out.col_max && out.row_min <= out.row_max;
}

/// Rasterises `t` (triangle `id`) into rows [row_begin, row_end) of `raster`.
void rasterize_rows(const ScreenTriangle& t, std::int32_t id, int row_begin, int row_end,
                    MeshRaster& raster) {
    // Edge functions: w_k(u, v) is twice the signed area of the sub-triangle opposite corner k.
    const double area =
        (t.u[1] - t.u[0]) * (t.v[2] - t.v[0]) - (t.u[2] - t.u[0]) * (t.v[1] - t.v[0]);
    if (!(std::abs(area) > 1e-12)) return;  // degenerate in the image: seen edge-on
    const double inv_area = 1.0 / area;
    const int r0 = std::max(row_begin, t.row_min);
    const int r1 = std::min(row_end - 1, t.row_max);
    for (int row = r0; row <= r1; ++row) {
        for (int col = t.col_min; col <= t.col_max; ++col) {
            const double u = col, v = row;
            const double b0 =
                ((t.u[1] - u) * (t.v[2] - v) - (t.u[2] - u) * (t.v[1] - v)) * inv_area;
            const double b1 =
                ((t.u[2] - u) * (t.v[0] - v) - (t.u[0] - u) * (t.v[2] - v)) * inv_area;
            const double b2 = 1.0 - b0 - b1;
            if (b0 < 0.0 || b1 < 0.0 || b2 < 0.0) continue;
            // 1/z is affine in the image: perspective-correct depth.
            const double inv_z = b0 * t.inv_z[0] + b1 * t.inv_z[1] + b2 * t.inv_z[2];
            const float z = static_cast<float>(1.0 / inv_z);
            const std::size_t i = raster.index(col, row);
            if (z < raster.depth_m[i]) {
                raster.depth_m[i] = z;
                raster.triangle[i] = id;
            }
        }
    }
}

}  // namespace
}  // namespace mesh_raster_internal

MeshRaster rasterize_mesh(const TriangleMesh& mesh, const RigCamera& camera,
                          const Eigen::Isometry3d& T_map_camera, double near_m) {
    using namespace mesh_raster_internal;
    MeshRaster raster;
    raster.width = camera.width;
    raster.height = camera.height;
    const std::size_t pixels = static_cast<std::size_t>(camera.width) * camera.height;
    raster.depth_m.assign(pixels, std::numeric_limits<float>::infinity());
    raster.triangle.assign(pixels, -1);
    if (mesh.triangles.empty() || pixels == 0) return raster;

    // Every vertex projected once; triangles only keep the rows they span (-1: not in view),
    // so a view costs the mesh's size in bytes, not a copy of it.
    const Eigen::Isometry3d T_camera_map = T_map_camera.inverse();
    std::vector<ScreenVertex> screen(mesh.vertices.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, screen.size(), 4096),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              const Eigen::Vector3d p =
                                  T_camera_map * mesh.vertices[i].cast<double>();
                              if (!(p.z() >= near_m)) continue;
                              ScreenVertex& s = screen[i];
                              s.inv_z = 1.0 / p.z();
                              s.u = camera.fx * p.x() * s.inv_z + camera.cx;
                              s.v = camera.fy * p.y() * s.inv_z + camera.cy;
                          }
                      });
    const std::size_t n = mesh.triangles.size();
    std::vector<std::array<std::int16_t, 2>> rows(n, {-1, -1});  // kMaxSide fits in int16
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const tbb::blocked_range<
                                                                       std::size_t>& r) {
        ScreenTriangle t;
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            if (!screen_triangle(mesh.triangles[i], screen, camera, t)) continue;
            rows[i] = {static_cast<std::int16_t>(t.row_min), static_cast<std::int16_t>(t.row_max)};
        }
    });
    // Bin the triangles by band of rows (counting sort keeps them in index order per band).
    const int bands = (camera.height + kBandRows - 1) / kBandRows;
    std::vector<std::size_t> band_start(static_cast<std::size_t>(bands) + 1, 0);
    for (std::size_t t = 0; t < n; ++t) {
        if (rows[t][0] < 0) continue;
        for (int b = rows[t][0] / kBandRows; b <= rows[t][1] / kBandRows; ++b) {
            ++band_start[static_cast<std::size_t>(b) + 1];
        }
    }
    for (int b = 0; b < bands; ++b) band_start[b + 1] += band_start[b];
    std::vector<std::int32_t> binned(band_start.back());
    std::vector<std::size_t> fill(band_start.begin(), band_start.end() - 1);
    for (std::size_t t = 0; t < n; ++t) {
        if (rows[t][0] < 0) continue;
        for (int b = rows[t][0] / kBandRows; b <= rows[t][1] / kBandRows; ++b) {
            binned[fill[b]++] = static_cast<std::int32_t>(t);
        }
    }
    tbb::parallel_for(tbb::blocked_range<int>(0, bands, 1), [&](const tbb::blocked_range<int>& r) {
        ScreenTriangle t;
        for (int b = r.begin(); b != r.end(); ++b) {
            const int row_begin = b * kBandRows;
            const int row_end = std::min(camera.height, row_begin + kBandRows);
            for (std::size_t k = band_start[b]; k < band_start[b + 1]; ++k) {
                const std::int32_t id = binned[k];
                screen_triangle(mesh.triangles[id], screen, camera, t);
                rasterize_rows(t, id, row_begin, row_end, raster);
            }
        }
    });
    return raster;
}

PixelTriangleHit pixel_triangle_hit(const TriangleMesh& mesh, std::int32_t triangle,
                                    const RigCamera& camera, const Eigen::Isometry3d& T_camera_map,
                                    int u, int v) {
    PixelTriangleHit hit;
    const Eigen::Vector3i& tri = mesh.triangles[triangle];
    const Eigen::Vector3d a = T_camera_map * mesh.vertices[tri[0]].cast<double>();
    hit.edge1 = T_camera_map * mesh.vertices[tri[1]].cast<double>() - a;
    hit.edge2 = T_camera_map * mesh.vertices[tri[2]].cast<double>() - a;
    hit.ray = camera.pixel_ray(u, v);
    const Eigen::Vector3d pv = hit.ray.cross(hit.edge2);
    const double det = hit.edge1.dot(pv);
    if (!(std::abs(det) > 1e-15)) return hit;
    const Eigen::Vector3d s = -a;  // the ray starts at the camera's centre
    const Eigen::Vector3d qv = s.cross(hit.edge1);
    const double w1 = std::clamp(s.dot(pv) / det, 0.0, 1.0);
    const double w2 = std::clamp(hit.ray.dot(qv) / det, 0.0, 1.0 - w1);
    hit.weights = {1.0 - w1 - w2, w1, w2};
    hit.crosses_plane = true;
    hit.distance_m = hit.edge2.dot(qv) / det;
    return hit;
}

}  // namespace shine
