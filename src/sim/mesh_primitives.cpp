#include "shine/sim/mesh_primitives.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <unordered_map>

#include "shine/core/error.hpp"

namespace shine::sim {
namespace primitives_internal {

/// Twice the signed area of a 2D triangle (positive when counter-clockwise).
float cross2(const Eigen::Vector2f& a, const Eigen::Vector2f& b, const Eigen::Vector2f& c) {
    return (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
}

float signed_area2(const std::vector<Eigen::Vector2f>& polygon) {
    float area2 = 0.0f;
    for (std::size_t i = 0; i < polygon.size(); ++i) {
        const auto& p = polygon[i];
        const auto& q = polygon[(i + 1) % polygon.size()];
        area2 += p.x() * q.y() - q.x() * p.y();
    }
    return area2;
}

/// Ear clipping of a simple counter-clockwise polygon; returns CCW index triples.
std::vector<Eigen::Vector3i> ear_clip(const std::vector<Eigen::Vector2f>& polygon) {
    std::vector<int> remaining(polygon.size());
    for (std::size_t i = 0; i < polygon.size(); ++i) remaining[i] = static_cast<int>(i);
    std::vector<Eigen::Vector3i> triangles;
    while (remaining.size() > 3) {
        bool clipped = false;
        const std::size_t n = remaining.size();
        for (std::size_t i = 0; i < n && !clipped; ++i) {
            const int ia = remaining[(i + n - 1) % n];
            const int ib = remaining[i];
            const int ic = remaining[(i + 1) % n];
            const auto& a = polygon[ia];
            const auto& b = polygon[ib];
            const auto& c = polygon[ic];
            if (cross2(a, b, c) <= 0.0f) continue;  // reflex or collinear: not an ear
            bool contains_other = false;
            for (const int j : remaining) {
                if (j == ia || j == ib || j == ic) continue;
                const auto& p = polygon[j];
                if (cross2(a, b, p) >= 0.0f && cross2(b, c, p) >= 0.0f && cross2(c, a, p) >= 0.0f) {
                    contains_other = true;
                    break;
                }
            }
            if (contains_other) continue;
            triangles.emplace_back(ia, ib, ic);
            remaining.erase(remaining.begin() + static_cast<std::ptrdiff_t>(i));
            clipped = true;
        }
        if (!clipped) {
            throw ConfigError("make_prism_mesh: polygon with " + std::to_string(polygon.size()) +
                              " vertices is not simple (no ear found); pass a simple polygon");
        }
    }
    triangles.emplace_back(remaining[0], remaining[1], remaining[2]);
    return triangles;
}

std::uint64_t edge_key(int a, int b) {
    const auto lo = static_cast<std::uint64_t>(std::min(a, b));
    const auto hi = static_cast<std::uint64_t>(std::max(a, b));
    return (lo << 32) | hi;
}

/// Index (0, 1, 2) of the longest edge (t[i], t[(i+1)%3]); ties broken by the edge key so that
/// the choice is deterministic.
int longest_edge(const TriangleMesh& mesh, const Eigen::Vector3i& t) {
    int best = 0;
    float best_len_sq = -1.0f;
    std::uint64_t best_key = 0;
    for (int i = 0; i < 3; ++i) {
        const int a = t[i];
        const int b = t[(i + 1) % 3];
        const float len_sq = (mesh.vertices[a] - mesh.vertices[b]).squaredNorm();
        const std::uint64_t key = edge_key(a, b);
        if (len_sq > best_len_sq || (len_sq == best_len_sq && key > best_key)) {
            best = i;
            best_len_sq = len_sq;
            best_key = key;
        }
    }
    return best;
}

bool inside_polygon(const std::vector<Eigen::Vector2f>& polygon, double x, double y) {
    bool inside = false;
    for (std::size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
        const double ax = polygon[i].x(), ay = polygon[i].y();
        const double bx = polygon[j].x(), by = polygon[j].y();
        if ((ay > y) != (by > y) && x < (bx - ax) * (y - ay) / (by - ay) + ax) inside = !inside;
    }
    return inside;
}

/// Grid coordinates over sorted break values: every interval split into equal steps of at most
/// `step`. `break_index[k]` is the grid index of breaks[k].
void subdivide(const std::vector<float>& breaks, double step, std::vector<float>& grid,
               std::vector<int>& break_index) {
    grid.clear();
    break_index.clear();
    grid.push_back(breaks[0]);
    break_index.push_back(0);
    for (std::size_t k = 1; k < breaks.size(); ++k) {
        const double a = breaks[k - 1], b = breaks[k];
        const int n = std::max(1, static_cast<int>(std::ceil((b - a) / step)));
        for (int i = 1; i < n; ++i) grid.push_back(static_cast<float>(a + (b - a) * i / n));
        grid.push_back(breaks[k]);
        break_index.push_back(static_cast<int>(grid.size()) - 1);
    }
}

}  // namespace primitives_internal

using namespace primitives_internal;

TriangleMesh make_box_mesh(const Eigen::Vector3f& min_corner_m,
                           const Eigen::Vector3f& max_corner_m) {
    const Eigen::Vector3f size = max_corner_m - min_corner_m;
    if (!(size.minCoeff() > 0.0f)) {
        throw ConfigError("make_box_mesh: box extents must be positive, got " +
                          std::to_string(size.x()) + " x " + std::to_string(size.y()) + " x " +
                          std::to_string(size.z()) + " m");
    }
    const std::vector<Eigen::Vector2f> rectangle = {{min_corner_m.x(), min_corner_m.y()},
                                                    {max_corner_m.x(), min_corner_m.y()},
                                                    {max_corner_m.x(), max_corner_m.y()},
                                                    {min_corner_m.x(), max_corner_m.y()}};
    TriangleMesh mesh = make_prism_mesh(rectangle, size.z());
    for (auto& v : mesh.vertices) v.z() += min_corner_m.z();
    return mesh;
}

TriangleMesh make_prism_mesh(const std::vector<Eigen::Vector2f>& polygon_ccw_m, float height_m) {
    if (polygon_ccw_m.size() < 3) {
        throw ConfigError("make_prism_mesh: a polygon needs at least 3 vertices, got " +
                          std::to_string(polygon_ccw_m.size()));
    }
    if (!(height_m > 0.0f)) {
        throw ConfigError("make_prism_mesh: height must be positive, got " +
                          std::to_string(height_m) + " m");
    }
    if (!(signed_area2(polygon_ccw_m) > 0.0f)) {
        throw ConfigError(
            "make_prism_mesh: polygon is clockwise or has zero area; list its vertices "
            "counter-clockwise");
    }
    const int n = static_cast<int>(polygon_ccw_m.size());
    TriangleMesh mesh;
    mesh.vertices.reserve(2 * n);
    for (const auto& p : polygon_ccw_m) mesh.vertices.emplace_back(p.x(), p.y(), 0.0f);
    for (const auto& p : polygon_ccw_m) mesh.vertices.emplace_back(p.x(), p.y(), height_m);
    for (const auto& t : ear_clip(polygon_ccw_m)) {
        mesh.triangles.emplace_back(t[0], t[2], t[1]);              // bottom cap faces -z
        mesh.triangles.emplace_back(n + t[0], n + t[1], n + t[2]);  // top cap faces +z
    }
    for (int i = 0; i < n; ++i) {
        const int j = (i + 1) % n;
        // Walls: the outward normal of a CCW edge direction d is d x z.
        mesh.triangles.emplace_back(i, j, n + j);
        mesh.triangles.emplace_back(i, n + j, n + i);
    }
    return mesh;
}

TriangleMesh make_grid_prism_mesh(const std::vector<Eigen::Vector2f>& polygon_ccw_m, float z0_m,
                                  float z1_m, float max_edge_m) {
    const std::size_t n = polygon_ccw_m.size();
    if (n < 4 || !(z1_m > z0_m) || !(max_edge_m > 0.0f)) {
        throw ConfigError(
            "make_grid_prism_mesh: need >= 4 polygon vertices, z1 > z0 and "
            "max_edge > 0, got " +
            std::to_string(n) + " vertices, z " + std::to_string(z0_m) + " .. " +
            std::to_string(z1_m) + " m, max edge " + std::to_string(max_edge_m) + " m");
    }
    for (std::size_t i = 0; i < n; ++i) {
        const auto& p = polygon_ccw_m[i];
        const auto& q = polygon_ccw_m[(i + 1) % n];
        if ((p.x() != q.x()) == (p.y() != q.y())) {
            throw ConfigError("make_grid_prism_mesh: polygon edge " + std::to_string(i) +
                              " is not parallel to x or y (or has zero length); the grid "
                              "tessellation needs a rectilinear polygon");
        }
    }
    if (!(signed_area2(polygon_ccw_m) > 0.0f)) {
        throw ConfigError("make_grid_prism_mesh: polygon is clockwise; list it counter-clockwise");
    }
    const double step = 0.999 * max_edge_m / std::sqrt(2.0);  // cell diagonal <= max_edge
    std::vector<float> xs, ys;
    for (const auto& p : polygon_ccw_m) {
        xs.push_back(p.x());
        ys.push_back(p.y());
    }
    for (auto* v : {&xs, &ys}) {
        std::sort(v->begin(), v->end());
        v->erase(std::unique(v->begin(), v->end()), v->end());
    }
    std::vector<float> gx, gy, gz;
    std::vector<int> x_index, y_index, z_index;
    subdivide(xs, step, gx, x_index);
    subdivide(ys, step, gy, y_index);
    subdivide({z0_m, z1_m}, step, gz, z_index);
    const auto nx = static_cast<std::uint64_t>(gx.size());
    const auto ny = static_cast<std::uint64_t>(gy.size());
    const auto nz = static_cast<std::uint64_t>(gz.size());

    TriangleMesh mesh;
    std::unordered_map<std::uint64_t, int> vertex_of;
    auto vertex = [&](int ix, int iy, int iz) {
        const std::uint64_t key = (static_cast<std::uint64_t>(ix) * ny + iy) * nz + iz;
        const auto [it, inserted] = vertex_of.emplace(key, static_cast<int>(mesh.vertices.size()));
        if (inserted) mesh.vertices.emplace_back(gx[ix], gy[iy], gz[iz]);
        return it->second;
    };
    // Caps: grid cells whose centre is inside the polygon.
    const int top = static_cast<int>(nz) - 1;
    for (int ix = 0; ix + 1 < static_cast<int>(nx); ++ix) {
        for (int iy = 0; iy + 1 < static_cast<int>(ny); ++iy) {
            if (!inside_polygon(polygon_ccw_m, 0.5 * (gx[ix] + gx[ix + 1]),
                                0.5 * (gy[iy] + gy[iy + 1]))) {
                continue;
            }
            for (const int iz : {0, top}) {
                const int a = vertex(ix, iy, iz), b = vertex(ix + 1, iy, iz),
                          c = vertex(ix + 1, iy + 1, iz), d = vertex(ix, iy + 1, iz);
                if (iz == top) {
                    mesh.triangles.emplace_back(a, b, c);
                    mesh.triangles.emplace_back(a, c, d);
                } else {
                    mesh.triangles.emplace_back(a, c, b);
                    mesh.triangles.emplace_back(a, d, c);
                }
            }
        }
    }
    // Walls: each polygon edge walks the grid lines it covers.
    auto grid_index = [](const std::vector<float>& breaks, const std::vector<int>& index, float v) {
        return index[std::lower_bound(breaks.begin(), breaks.end(), v) - breaks.begin()];
    };
    for (std::size_t i = 0; i < n; ++i) {
        const auto& p = polygon_ccw_m[i];
        const auto& q = polygon_ccw_m[(i + 1) % n];
        const int ix0 = grid_index(xs, x_index, p.x()), ix1 = grid_index(xs, x_index, q.x());
        const int iy0 = grid_index(ys, y_index, p.y()), iy1 = grid_index(ys, y_index, q.y());
        const int steps = std::abs(ix1 - ix0) + std::abs(iy1 - iy0);
        const int dx = (ix1 > ix0) - (ix1 < ix0), dy = (iy1 > iy0) - (iy1 < iy0);
        for (int k = 0; k < steps; ++k) {
            for (int iz = 0; iz < top; ++iz) {
                const int b0 = vertex(ix0 + k * dx, iy0 + k * dy, iz);
                const int b1 = vertex(ix0 + (k + 1) * dx, iy0 + (k + 1) * dy, iz);
                const int t1 = vertex(ix0 + (k + 1) * dx, iy0 + (k + 1) * dy, iz + 1);
                const int t0 = vertex(ix0 + k * dx, iy0 + k * dy, iz + 1);
                mesh.triangles.emplace_back(b0, b1, t1);
                mesh.triangles.emplace_back(b0, t1, t0);
            }
        }
    }
    return mesh;
}

TriangleMesh make_cylinder_mesh(float radius_m, float height_m, int segments) {
    if (!(radius_m > 0.0f) || !(height_m > 0.0f) || segments < 3) {
        throw ConfigError(
            "make_cylinder_mesh: need radius > 0, height > 0 and >= 3 segments, got " +
            std::to_string(radius_m) + " m, " + std::to_string(height_m) + " m, " +
            std::to_string(segments));
    }
    TriangleMesh mesh;
    const int bottom_center = 0;
    const int top_center = 1;
    mesh.vertices.emplace_back(0.0f, 0.0f, 0.0f);
    mesh.vertices.emplace_back(0.0f, 0.0f, height_m);
    for (int i = 0; i < segments; ++i) {
        const double angle = 2.0 * M_PI * i / segments;
        const float x = radius_m * static_cast<float>(std::cos(angle));
        const float y = radius_m * static_cast<float>(std::sin(angle));
        mesh.vertices.emplace_back(x, y, 0.0f);
        mesh.vertices.emplace_back(x, y, height_m);
    }
    for (int i = 0; i < segments; ++i) {
        const int j = (i + 1) % segments;
        const int b_i = 2 + 2 * i, t_i = b_i + 1;
        const int b_j = 2 + 2 * j, t_j = b_j + 1;
        mesh.triangles.emplace_back(bottom_center, b_j, b_i);
        mesh.triangles.emplace_back(top_center, t_i, t_j);
        mesh.triangles.emplace_back(b_i, b_j, t_j);
        mesh.triangles.emplace_back(b_i, t_j, t_i);
    }
    return mesh;
}

TriangleMesh make_grid_cylinder_mesh(float radius_m, float height_m, float max_edge_m) {
    if (!(radius_m > 0.0f) || !(height_m > 0.0f) || !(max_edge_m > 0.0f)) {
        throw ConfigError("make_grid_cylinder_mesh: need radius, height and max_edge > 0, got " +
                          std::to_string(radius_m) + ", " + std::to_string(height_m) + ", " +
                          std::to_string(max_edge_m) + " m");
    }
    const double step = 0.999 * max_edge_m / std::sqrt(2.0);
    // Chord 2 r sin(pi / n) <= step.
    const int segments = std::max(
        8, static_cast<int>(std::ceil(M_PI / std::asin(std::min(1.0, step / (2.0 * radius_m))))));
    const int rings = std::max(1, static_cast<int>(std::ceil(height_m / step)));
    TriangleMesh mesh;
    mesh.vertices.emplace_back(0.0f, 0.0f, 0.0f);
    mesh.vertices.emplace_back(0.0f, 0.0f, height_m);
    auto ring_vertex = [segments](int ring, int i) { return 2 + ring * segments + i % segments; };
    for (int ring = 0; ring <= rings; ++ring) {
        const float z = ring == rings ? height_m : static_cast<float>(height_m * ring / rings);
        for (int i = 0; i < segments; ++i) {
            const double angle = 2.0 * M_PI * i / segments;
            mesh.vertices.emplace_back(radius_m * static_cast<float>(std::cos(angle)),
                                       radius_m * static_cast<float>(std::sin(angle)), z);
        }
    }
    for (int i = 0; i < segments; ++i) {
        mesh.triangles.emplace_back(0, ring_vertex(0, i + 1), ring_vertex(0, i));
        mesh.triangles.emplace_back(1, ring_vertex(rings, i), ring_vertex(rings, i + 1));
        for (int ring = 0; ring < rings; ++ring) {
            const int b0 = ring_vertex(ring, i), b1 = ring_vertex(ring, i + 1);
            const int t0 = ring_vertex(ring + 1, i), t1 = ring_vertex(ring + 1, i + 1);
            mesh.triangles.emplace_back(b0, b1, t1);
            mesh.triangles.emplace_back(b0, t1, t0);
        }
    }
    return mesh;
}

TriangleMesh make_ellipsoid_mesh(const Eigen::Vector3f& radii_m, int subdivisions) {
    if (!(radii_m.minCoeff() > 0.0f) || subdivisions < 0) {
        throw ConfigError("make_ellipsoid_mesh: radii must be positive and subdivisions >= 0");
    }
    const float phi = (1.0f + std::sqrt(5.0f)) / 2.0f;
    TriangleMesh mesh;
    mesh.vertices = {{-1, phi, 0}, {1, phi, 0}, {-1, -phi, 0}, {1, -phi, 0},
                     {0, -1, phi}, {0, 1, phi}, {0, -1, -phi}, {0, 1, -phi},
                     {phi, 0, -1}, {phi, 0, 1}, {-phi, 0, -1}, {-phi, 0, 1}};
    mesh.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                      {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                      {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                      {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    for (auto& v : mesh.vertices) v.normalize();
    for (int level = 0; level < subdivisions; ++level) {
        std::unordered_map<std::uint64_t, int> midpoints;
        auto midpoint = [&](int a, int b) {
            const auto [it, inserted] =
                midpoints.emplace(edge_key(a, b), static_cast<int>(mesh.vertices.size()));
            if (inserted) {
                const Eigen::Vector3f m = (mesh.vertices[a] + mesh.vertices[b]).normalized();
                mesh.vertices.push_back(m);
            }
            return it->second;
        };
        std::vector<Eigen::Vector3i> finer;
        finer.reserve(mesh.triangles.size() * 4);
        for (const auto& t : mesh.triangles) {
            const int ab = midpoint(t[0], t[1]);
            const int bc = midpoint(t[1], t[2]);
            const int ca = midpoint(t[2], t[0]);
            finer.emplace_back(t[0], ab, ca);
            finer.emplace_back(t[1], bc, ab);
            finer.emplace_back(t[2], ca, bc);
            finer.emplace_back(ab, bc, ca);
        }
        mesh.triangles = std::move(finer);
    }
    // Orient every face outward (the sphere is star-shaped around its centre).
    for (auto& t : mesh.triangles) {
        const Eigen::Vector3f& a = mesh.vertices[t[0]];
        const Eigen::Vector3f normal = (mesh.vertices[t[1]] - a).cross(mesh.vertices[t[2]] - a);
        if (normal.dot(a + mesh.vertices[t[1]] + mesh.vertices[t[2]]) < 0.0f) std::swap(t[1], t[2]);
    }
    for (auto& v : mesh.vertices) v = v.cwiseProduct(radii_m);
    return mesh;
}

void transform_mesh(TriangleMesh& mesh, const Eigen::Affine3f& T) {
    for (auto& v : mesh.vertices) v = T * v;
    if (T.linear().determinant() < 0.0f) {
        for (auto& t : mesh.triangles) std::swap(t[1], t[2]);
    }
}

void append_mesh(TriangleMesh& mesh, const TriangleMesh& part) {
    const int offset = static_cast<int>(mesh.vertices.size());
    mesh.vertices.insert(mesh.vertices.end(), part.vertices.begin(), part.vertices.end());
    mesh.triangles.reserve(mesh.triangles.size() + part.triangles.size());
    for (const auto& t : part.triangles) {
        mesh.triangles.emplace_back(t + Eigen::Vector3i::Constant(offset));
    }
}

void refine_to_max_edge(TriangleMesh& mesh, float max_edge_m) {
    if (!(max_edge_m > 0.0f)) {
        throw ConfigError("refine_to_max_edge: max_edge_m must be positive, got " +
                          std::to_string(max_edge_m));
    }
    const float max_len_sq = max_edge_m * max_edge_m;
    for (;;) {
        // Pass 1: mark every edge that is too long (value: midpoint vertex, -1 = not made yet).
        std::unordered_map<std::uint64_t, int> marked;
        for (const auto& t : mesh.triangles) {
            for (int i = 0; i < 3; ++i) {
                const int a = t[i];
                const int b = t[(i + 1) % 3];
                if ((mesh.vertices[a] - mesh.vertices[b]).squaredNorm() > max_len_sq) {
                    marked.emplace(edge_key(a, b), -1);
                }
            }
        }
        if (marked.empty()) return;
        // Pass 2: closure. A triangle with any marked edge must have its longest edge marked, so
        // it is always bisected along its longest edge first (Rivara); this keeps angles bounded
        // away from zero and the refinement conforming.
        std::vector<int> longest(mesh.triangles.size());
        for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
            longest[i] = longest_edge(mesh, mesh.triangles[i]);
        }
        for (bool changed = true; changed;) {
            changed = false;
            for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
                const auto& t = mesh.triangles[i];
                const int l = longest[i];
                const std::uint64_t longest_key = edge_key(t[l], t[(l + 1) % 3]);
                if (marked.count(longest_key)) continue;
                const bool any = marked.count(edge_key(t[0], t[1])) ||
                                 marked.count(edge_key(t[1], t[2])) ||
                                 marked.count(edge_key(t[2], t[0]));
                if (any) {
                    marked.emplace(longest_key, -1);
                    changed = true;
                }
            }
        }
        // Pass 3: split. Midpoints are created in triangle order, so the result is deterministic.
        auto midpoint = [&](int a, int b) -> int {
            const auto it = marked.find(edge_key(a, b));
            if (it == marked.end()) return -1;
            if (it->second < 0) {
                const Eigen::Vector3f m = 0.5f * (mesh.vertices[a] + mesh.vertices[b]);
                it->second = static_cast<int>(mesh.vertices.size());
                mesh.vertices.push_back(m);
            }
            return it->second;
        };
        std::vector<Eigen::Vector3i> finer;
        finer.reserve(mesh.triangles.size() * 2);
        for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
            const auto& t = mesh.triangles[i];
            const int l = longest[i];
            const int a = t[l], b = t[(l + 1) % 3], c = t[(l + 2) % 3];
            const int m = midpoint(a, b);
            if (m < 0) {
                finer.push_back(t);
                continue;
            }
            const int m_ca = midpoint(c, a);
            if (m_ca < 0) {
                finer.emplace_back(a, m, c);
            } else {
                finer.emplace_back(a, m, m_ca);
                finer.emplace_back(m, c, m_ca);
            }
            const int m_bc = midpoint(b, c);
            if (m_bc < 0) {
                finer.emplace_back(m, b, c);
            } else {
                finer.emplace_back(m, b, m_bc);
                finer.emplace_back(m, m_bc, c);
            }
        }
        mesh.triangles = std::move(finer);
    }
}

float max_edge_length(const TriangleMesh& mesh) {
    float max_len_sq = 0.0f;
    for (const auto& t : mesh.triangles) {
        for (int i = 0; i < 3; ++i) {
            max_len_sq = std::max(
                max_len_sq, (mesh.vertices[t[i]] - mesh.vertices[t[(i + 1) % 3]]).squaredNorm());
        }
    }
    return std::sqrt(max_len_sq);
}

}  // namespace shine::sim
