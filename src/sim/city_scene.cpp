#include "shine/sim/city_scene.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <mutex>
#include <string>

#include "shine/core/progress.hpp"
#include "shine/sim/mesh_primitives.hpp"

namespace shine::sim {
namespace city_scene_internal {

/// Sorted grid coordinates over [lo, hi] through every break inside it, steps at most `step_m`.
std::vector<double> grid_lines(double lo, double hi, std::initializer_list<double> inner,
                               double step_m) {
    std::vector<double> breaks = {lo, hi};
    for (const double b : inner) {
        if (b > lo && b < hi) breaks.push_back(b);
    }
    std::sort(breaks.begin(), breaks.end());
    breaks.erase(std::unique(breaks.begin(), breaks.end()), breaks.end());
    std::vector<double> lines = {breaks.front()};
    for (std::size_t k = 1; k < breaks.size(); ++k) {
        const double a = breaks[k - 1], b = breaks[k];
        const int n = std::max(1, static_cast<int>(std::ceil((b - a) / step_m)));
        for (int i = 1; i < n; ++i) lines.push_back(a + (b - a) * i / n);
        lines.push_back(b);
    }
    return lines;
}

/// Moves a street built along +x from the origin to its place: a row block is shifted, a rung block
/// turned by +90 degrees (street x -> world y, street y -> world -x) and shifted. Coordinates are
/// summed in double and rounded once, so the block's ends land exactly on the 1/8 m grid lines the
/// junctions use.
void place_street(TriangleMesh& mesh, const StreetSegment& segment) {
    for (Eigen::Vector3f& v : mesh.vertices) {
        const double x = v.x(), y = v.y();
        if (segment.along_y) {
            v.x() = static_cast<float>(segment.origin_m.x() - y);
            v.y() = static_cast<float>(segment.origin_m.y() + x);
        } else {
            v.x() = static_cast<float>(segment.origin_m.x() + x);
            v.y() = static_cast<float>(segment.origin_m.y() + y);
        }
    }
}

}  // namespace city_scene_internal

using namespace city_scene_internal;

TriangleMesh make_junction_ground(const CityRoute& route, const Junction& junction) {
    const StreetLine& rung = route.rungs.at(junction.rung);
    const StreetLine& row = route.rows.at(junction.row);
    const double cx = rung.center_m, cy = row.center_m;
    const double step_m = 0.999 * route.street.max_edge_length_m / std::sqrt(2.0);
    const auto& area = junction.area_m;
    const std::vector<double> xs = grid_lines(area.min().x(), area.max().x(),
                                              {cx - rung.curb_outer_m(), cx - rung.half_road_m,
                                               cx + rung.half_road_m, cx + rung.curb_outer_m()},
                                              step_m);
    const std::vector<double> ys = grid_lines(area.min().y(), area.max().y(),
                                              {cy - row.curb_outer_m(), cy - row.half_road_m,
                                               cy + row.half_road_m, cy + row.curb_outer_m()},
                                              step_m);
    const int nx = static_cast<int>(xs.size()) - 1;
    const int ny = static_cast<int>(ys.size()) - 1;
    // Level of each cell: 0 road, 1 sidewalk or lot.
    std::vector<std::uint8_t> level(static_cast<std::size_t>(nx) * ny);
    auto cell = [nx](int ix, int iy) { return static_cast<std::size_t>(iy) * nx + ix; };
    for (int iy = 0; iy < ny; ++iy) {
        for (int ix = 0; ix < nx; ++ix) {
            const double dx = 0.5 * (xs[ix] + xs[ix + 1]) - cx;
            const double dy = 0.5 * (ys[iy] + ys[iy + 1]) - cy;
            const bool in_rung_road = std::abs(dx) < rung.half_road_m;
            const bool in_row_road = std::abs(dy) < row.half_road_m;
            const bool road =
                (in_rung_road && in_row_road) ||
                (in_row_road &&
                 ((dx < 0.0 && junction.arm_west) || (dx > 0.0 && junction.arm_east))) ||
                (in_rung_road &&
                 ((dy < 0.0 && junction.arm_south) || (dy > 0.0 && junction.arm_north)));
            level[cell(ix, iy)] = road ? 0 : 1;
        }
    }
    // Vertices at grid corner (ix, iy), height step k of a curb split into nv steps (k = 0 road,
    // k = nv sidewalk), made on first use.
    const double curb_m = route.street.curb_height_m;
    const int nv = std::max(1, static_cast<int>(std::ceil(curb_m / step_m)));
    TriangleMesh mesh;
    std::vector<int> vertex_index(static_cast<std::size_t>(nx + 1) * (ny + 1) * (nv + 1), -1);
    auto vertex = [&](int ix, int iy, int k) {
        int& index = vertex_index[(static_cast<std::size_t>(iy) * (nx + 1) + ix) * (nv + 1) + k];
        if (index < 0) {
            index = static_cast<int>(mesh.vertices.size());
            const double z = k == nv ? curb_m : curb_m * k / nv;
            mesh.vertices.emplace_back(static_cast<float>(xs[ix]), static_cast<float>(ys[iy]),
                                       static_cast<float>(z));
        }
        return index;
    };
    // Flat cells, counter-clockwise seen from above: normals up.
    for (int iy = 0; iy < ny; ++iy) {
        for (int ix = 0; ix < nx; ++ix) {
            const int k = level[cell(ix, iy)] ? nv : 0;
            const int a = vertex(ix, iy, k), b = vertex(ix + 1, iy, k);
            const int c = vertex(ix + 1, iy + 1, k), d = vertex(ix, iy + 1, k);
            mesh.triangles.emplace_back(a, b, c);
            mesh.triangles.emplace_back(a, c, d);
        }
    }
    // Curb faces where a road cell meets a raised one, facing the road (`to_road`).
    auto add_wall = [&](int ix0, int iy0, int ix1, int iy1, const Eigen::Vector3f& to_road) {
        for (int k = 0; k < nv; ++k) {
            const int p0 = vertex(ix0, iy0, k), p1 = vertex(ix1, iy1, k);
            const int p2 = vertex(ix1, iy1, k + 1), p3 = vertex(ix0, iy0, k + 1);
            const Eigen::Vector3f normal = (mesh.vertices[p1] - mesh.vertices[p0])
                                               .cross(mesh.vertices[p2] - mesh.vertices[p0]);
            if (normal.dot(to_road) > 0.0f) {
                mesh.triangles.emplace_back(p0, p1, p2);
                mesh.triangles.emplace_back(p0, p2, p3);
            } else {
                mesh.triangles.emplace_back(p0, p2, p1);
                mesh.triangles.emplace_back(p0, p3, p2);
            }
        }
    };
    for (int iy = 0; iy < ny; ++iy) {
        for (int ix = 1; ix < nx; ++ix) {  // walls on x = xs[ix]
            const std::uint8_t left = level[cell(ix - 1, iy)], right = level[cell(ix, iy)];
            if (left != right) {
                add_wall(ix, iy, ix, iy + 1, Eigen::Vector3f(right == 0 ? 1.0f : -1.0f, 0, 0));
            }
        }
    }
    for (int iy = 1; iy < ny; ++iy) {
        for (int ix = 0; ix < nx; ++ix) {  // walls on y = ys[iy]
            const std::uint8_t below = level[cell(ix, iy - 1)], above = level[cell(ix, iy)];
            if (below != above) {
                add_wall(ix, iy, ix + 1, iy, Eigen::Vector3f(0, above == 0 ? 1.0f : -1.0f, 0));
            }
        }
    }
    return mesh;
}

CityScene make_city_scene(const CityRoute& route, bool show_progress) {
    const std::size_t n_streets = route.segments.size();
    const std::size_t n_junctions = route.junctions.size();
    std::vector<StreetScene> streets(n_streets);
    std::vector<TriangleMesh> grounds(n_junctions);
    Progress progress("scene", n_streets + n_junctions, show_progress);
    std::mutex progress_mutex;  // Progress is not thread-safe
    std::size_t done = 0;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n_streets + n_junctions, 1),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              if (i < n_streets) {
                                  streets[i] = make_street_scene(route.segments[i].scene);
                                  place_street(streets[i].mesh, route.segments[i]);
                              } else {
                                  grounds[i - n_streets] =
                                      make_junction_ground(route, route.junctions[i - n_streets]);
                              }
                              const std::lock_guard<std::mutex> lock(progress_mutex);
                              progress.update(++done, "streets and junctions");
                          }
                      });

    // Assemble in a fixed order, freeing each piece once copied.
    CityScene city;
    TriangleMesh& mesh = city.scene.mesh;
    std::size_t n_vertices = 0, n_triangles = 0;
    for (const StreetScene& s : streets) {
        n_vertices += s.mesh.vertices.size();
        n_triangles += s.mesh.triangles.size();
    }
    for (const TriangleMesh& g : grounds) {
        n_vertices += g.vertices.size();
        n_triangles += g.triangles.size();
    }
    mesh.vertices.reserve(n_vertices);
    mesh.triangles.reserve(n_triangles);
    std::size_t next_object = 0;
    for (StreetScene& street : streets) {
        const std::size_t first = mesh.triangles.size();
        std::size_t objects = 0;
        for (ScenePart part : street.parts) {
            objects = std::max(objects, part.object_index + 1);
            part.first_triangle += first;
            part.object_index += next_object;
            city.scene.parts.push_back(part);
        }
        next_object += objects;
        append_mesh(mesh, street.mesh);
        city.blocks.push_back({first, street.mesh.triangles.size()});
        street = StreetScene();
    }
    for (TriangleMesh& ground : grounds) {
        ScenePart part;
        part.kind = SceneObjectKind::kGround;
        part.object_index = next_object++;
        part.first_triangle = mesh.triangles.size();
        part.num_triangles = ground.triangles.size();
        part.closed = false;
        city.scene.parts.push_back(part);
        append_mesh(mesh, ground);
        city.blocks.push_back({part.first_triangle, part.num_triangles});
        ground = TriangleMesh();
    }
    progress.finish(std::to_string(mesh.triangles.size()) + " triangles");
    return city;
}

}  // namespace shine::sim
