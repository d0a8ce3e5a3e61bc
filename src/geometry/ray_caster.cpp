#include "shine/geometry/ray_caster.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "shine/core/error.hpp"

namespace shine {
namespace ray_caster_internal {

constexpr int kBins = 16;
constexpr int kMaxLeafSize = 4;
constexpr int kForcedLeafSize = 16;  ///< a node this small becomes a leaf if no split pays off
constexpr int kMaxDepth = 120;       ///< traversal stack holds kMaxDepth + 8 entries
constexpr int kStackSize = kMaxDepth + 8;

struct Box {
    Eigen::Vector3f lower = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
    Eigen::Vector3f upper = Eigen::Vector3f::Constant(-std::numeric_limits<float>::max());

    void extend(const Eigen::Vector3f& p) {
        lower = lower.cwiseMin(p);
        upper = upper.cwiseMax(p);
    }
    void extend(const Box& b) {
        lower = lower.cwiseMin(b.lower);
        upper = upper.cwiseMax(b.upper);
    }
    bool valid() const { return lower.x() <= upper.x(); }
    float half_area() const {
        if (!valid()) return 0.0f;
        const Eigen::Vector3f d = upper - lower;
        return d.x() * d.y() + d.y() * d.z() + d.z() * d.x();
    }
};

struct Primitive {
    Box box;
    Eigen::Vector3f centroid;
};

struct Builder {
    const std::vector<Primitive>& primitives;
    std::vector<std::int32_t>& order;
    std::vector<Box> node_boxes;
    std::vector<std::array<std::uint32_t, 3>> node_info;  // index, count, axis

    /// Builds the subtree over order[begin, end) and returns its node index.
    std::uint32_t build(std::size_t begin, std::size_t end, int depth) {
        const auto node = static_cast<std::uint32_t>(node_boxes.size());
        node_boxes.emplace_back();
        node_info.push_back({0, 0, 0});
        Box bounds, centroid_bounds;
        for (std::size_t i = begin; i < end; ++i) {
            bounds.extend(primitives[order[i]].box);
            centroid_bounds.extend(primitives[order[i]].centroid);
        }
        node_boxes[node] = bounds;
        const std::size_t count = end - begin;
        auto make_leaf = [&] {
            node_info[node] = {static_cast<std::uint32_t>(begin), static_cast<std::uint32_t>(count),
                               0};
            return node;
        };
        if (count <= static_cast<std::size_t>(kMaxLeafSize)) return make_leaf();
        if (depth >= kMaxDepth) {
            if (count > 0xFFFF) {
                throw ConfigError(
                    "RayCaster: BVH deeper than " + std::to_string(kMaxDepth) + " levels with " +
                    std::to_string(count) +
                    " triangles left; the mesh is degenerate (coincident triangles?)");
            }
            return make_leaf();
        }

        // Binned SAH over all three axes.
        int best_axis = -1;
        int best_split = -1;
        float best_cost = std::numeric_limits<float>::max();
        for (int axis = 0; axis < 3; ++axis) {
            const float lo = centroid_bounds.lower[axis];
            const float extent = centroid_bounds.upper[axis] - lo;
            if (!(extent > 0.0f)) continue;
            const float scale = kBins / extent;
            std::array<Box, kBins> bin_boxes;
            std::array<std::size_t, kBins> bin_counts{};
            for (std::size_t i = begin; i < end; ++i) {
                const Primitive& p = primitives[order[i]];
                const int b =
                    std::min(kBins - 1, static_cast<int>((p.centroid[axis] - lo) * scale));
                bin_boxes[b].extend(p.box);
                ++bin_counts[b];
            }
            std::array<float, kBins> right_area{};
            std::array<std::size_t, kBins> right_count{};
            Box right;
            std::size_t n_right = 0;
            for (int b = kBins - 1; b > 0; --b) {
                right.extend(bin_boxes[b]);
                n_right += bin_counts[b];
                right_area[b] = right.half_area();
                right_count[b] = n_right;
            }
            Box left;
            std::size_t n_left = 0;
            for (int b = 0; b < kBins - 1; ++b) {
                left.extend(bin_boxes[b]);
                n_left += bin_counts[b];
                if (n_left == 0 || right_count[b + 1] == 0) continue;
                const float cost = left.half_area() * static_cast<float>(n_left) +
                                   right_area[b + 1] * static_cast<float>(right_count[b + 1]);
                if (cost < best_cost) {
                    best_cost = cost;
                    best_axis = axis;
                    best_split = b;
                }
            }
        }

        std::size_t middle = begin + count / 2;
        int axis_for_node = 0;
        if (best_axis >= 0) {
            const float leaf_cost = bounds.half_area() * static_cast<float>(count);
            if (best_cost >= leaf_cost && count <= static_cast<std::size_t>(kForcedLeafSize)) {
                return make_leaf();
            }
            const float lo = centroid_bounds.lower[best_axis];
            const float scale = kBins / (centroid_bounds.upper[best_axis] - lo);
            const auto it = std::partition(
                order.begin() + static_cast<std::ptrdiff_t>(begin),
                order.begin() + static_cast<std::ptrdiff_t>(end), [&](std::int32_t id) {
                    const int b = std::min(
                        kBins - 1,
                        static_cast<int>((primitives[id].centroid[best_axis] - lo) * scale));
                    return b <= best_split;
                });
            middle = static_cast<std::size_t>(it - order.begin());
            axis_for_node = best_axis;
            if (middle == begin || middle == end) middle = begin + count / 2;
        } else if (count <= static_cast<std::size_t>(kForcedLeafSize)) {
            return make_leaf();  // all centroids coincide
        }
        build(begin, middle, depth + 1);
        const std::uint32_t right_child = build(middle, end, depth + 1);
        node_info[node] = {right_child, 0, static_cast<std::uint32_t>(axis_for_node)};
        return node;
    }
};

/// Pads a float box so that float rounding in the slab test can never cull a true hit.
float pad(float x, float direction) {
    const float margin = 1e-4f + 1e-6f * std::abs(x);
    return x + direction * margin;
}

}  // namespace ray_caster_internal

using namespace ray_caster_internal;

struct RayCaster::Ray {
    Eigen::Vector3d origin;
    Eigen::Vector3d direction;
    float origin_f[3];
    float inverse_direction_f[3];
};

bool intersect_ray_triangle(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                            const Eigen::Vector3d& v0, const Eigen::Vector3d& v1,
                            const Eigen::Vector3d& v2, double t_min, double t_max, double& t) {
    const Eigen::Vector3d e1 = v1 - v0;
    const Eigen::Vector3d e2 = v2 - v0;
    const Eigen::Vector3d p = direction.cross(e2);
    const double det = e1.dot(p);
    if (det == 0.0) return false;  // ray parallel to the triangle plane (or degenerate triangle)
    const double inv_det = 1.0 / det;
    const Eigen::Vector3d s = origin - v0;
    const double u = s.dot(p) * inv_det;
    if (u < 0.0 || u > 1.0) return false;
    const Eigen::Vector3d q = s.cross(e1);
    const double v = direction.dot(q) * inv_det;
    if (v < 0.0 || u + v > 1.0) return false;
    const double distance = e2.dot(q) * inv_det;
    if (distance < t_min || distance > t_max) return false;
    t = distance;
    return true;
}

RayCaster::RayCaster(const TriangleMesh& mesh) : RayCaster(mesh, 0, mesh.triangles.size()) {}

RayCaster::RayCaster(const TriangleMesh& mesh, std::size_t first_triangle,
                     std::size_t num_triangles) {
    if (first_triangle > mesh.triangles.size() ||
        num_triangles > mesh.triangles.size() - first_triangle) {
        throw ConfigError("RayCaster: triangles [" + std::to_string(first_triangle) + ", " +
                          std::to_string(first_triangle + num_triangles) +
                          ") are not all in a mesh of " + std::to_string(mesh.triangles.size()) +
                          " triangles");
    }
    if (mesh.triangles.size() >
        static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
        throw ConfigError("RayCaster: more than 2^31 triangles are not supported");
    }
    const std::size_t n = num_triangles;
    const auto n_vertices = static_cast<int>(mesh.vertices.size());
    std::vector<Primitive> primitives(n);
    for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector3i& t = mesh.triangles[first_triangle + i];
        Primitive& p = primitives[i];
        for (int k = 0; k < 3; ++k) {
            if (t[k] < 0 || t[k] >= n_vertices) {
                throw ConfigError("RayCaster: triangle " + std::to_string(first_triangle + i) +
                                  " has vertex index " + std::to_string(t[k]) +
                                  " but the mesh has " + std::to_string(n_vertices) + " vertices");
            }
            const Eigen::Vector3f& v = mesh.vertices[t[k]];
            if (!v.allFinite()) {
                throw ConfigError("RayCaster: vertex " + std::to_string(t[k]) + " is not finite");
            }
            p.box.extend(v);
        }
        for (int a = 0; a < 3; ++a) {
            p.box.lower[a] = pad(p.box.lower[a], -1.0f);
            p.box.upper[a] = pad(p.box.upper[a], 1.0f);
        }
        p.centroid = 0.5f * (p.box.lower + p.box.upper);
    }
    std::vector<std::int32_t> order(n);
    for (std::size_t i = 0; i < n; ++i) order[i] = static_cast<std::int32_t>(i);
    if (n == 0) return;

    Builder builder{primitives, order, {}, {}};
    builder.node_boxes.reserve(2 * n / kMaxLeafSize + 1);
    builder.node_info.reserve(2 * n / kMaxLeafSize + 1);
    builder.build(0, n, 0);

    nodes_.resize(builder.node_boxes.size());
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
        Node& node = nodes_[i];
        for (int a = 0; a < 3; ++a) {
            node.lower[a] = builder.node_boxes[i].lower[a];
            node.upper[a] = builder.node_boxes[i].upper[a];
        }
        node.index = builder.node_info[i][0];
        node.count = static_cast<std::uint16_t>(builder.node_info[i][1]);
        node.axis = static_cast<std::uint16_t>(builder.node_info[i][2]);
    }
    corners_.resize(9 * n);
    for (std::size_t slot = 0; slot < n; ++slot) {
        const Eigen::Vector3i& t = mesh.triangles[first_triangle + order[slot]];
        for (int k = 0; k < 3; ++k) {
            for (int a = 0; a < 3; ++a) corners_[9 * slot + 3 * k + a] = mesh.vertices[t[k]][a];
        }
    }
    // Slots name triangles by their index in the whole mesh.
    triangle_ids_.resize(n);
    for (std::size_t slot = 0; slot < n; ++slot) {
        triangle_ids_[slot] = static_cast<std::int32_t>(first_triangle) + order[slot];
    }
}

Eigen::AlignedBox3f RayCaster::bounds() const {
    if (nodes_.empty()) return Eigen::AlignedBox3f();  // empty box
    const Node& root = nodes_[0];
    return Eigen::AlignedBox3f(Eigen::Vector3f(root.lower[0], root.lower[1], root.lower[2]),
                               Eigen::Vector3f(root.upper[0], root.upper[1], root.upper[2]));
}

void RayCaster::test_leaf(const Node& node, const Ray& ray, double t_min_m, RayHit& best) const {
    const std::uint32_t end = node.index + node.count;
    for (std::uint32_t slot = node.index; slot < end; ++slot) {
        const float* c = &corners_[9 * static_cast<std::size_t>(slot)];
        const Eigen::Vector3d v0(c[0], c[1], c[2]);
        const Eigen::Vector3d v1(c[3], c[4], c[5]);
        const Eigen::Vector3d v2(c[6], c[7], c[8]);
        double t;
        if (!intersect_ray_triangle(ray.origin, ray.direction, v0, v1, v2, t_min_m, best.distance_m,
                                    t)) {
            continue;
        }
        const std::int32_t id = triangle_ids_[slot];
        // Ties (a ray through a shared edge) go to the lowest triangle id, so the answer does not
        // depend on the BVH layout.
        if (t < best.distance_m || best.triangle_id < 0 || id < best.triangle_id) {
            best.distance_m = t;
            best.triangle_id = id;
        }
    }
}

RayHit RayCaster::cast(const Eigen::Vector3d& origin_m, const Eigen::Vector3d& direction_unit,
                       double t_min_m, double t_max_m) const {
    RayHit best;
    best.distance_m = t_max_m;
    if (nodes_.empty()) {
        best.distance_m = std::numeric_limits<double>::infinity();
        return best;
    }
    Ray ray;
    ray.origin = origin_m;
    ray.direction = direction_unit;
    for (int a = 0; a < 3; ++a) {
        ray.origin_f[a] = static_cast<float>(origin_m[a]);
        double d = direction_unit[a];
        if (d == 0.0) d = std::copysign(1e-30, d);
        ray.inverse_direction_f[a] = static_cast<float>(1.0 / d);
    }
    // Box tests run in float with widened limits; the triangle test enforces [t_min, t_max]
    // exactly.
    const float t_near_limit = static_cast<float>(t_min_m) * (1.0f - 1e-5f) - 1e-5f;

    std::uint32_t stack[kStackSize];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& node = nodes_[stack[--top]];
        float t0 = t_near_limit;
        float t1 = std::isfinite(best.distance_m)
                       ? static_cast<float>(best.distance_m) * (1.0f + 1e-5f) + 1e-5f
                       : std::numeric_limits<float>::max();
        bool outside = false;
        for (int a = 0; a < 3 && !outside; ++a) {
            const float ta = (node.lower[a] - ray.origin_f[a]) * ray.inverse_direction_f[a];
            const float tb = (node.upper[a] - ray.origin_f[a]) * ray.inverse_direction_f[a];
            t0 = std::max(t0, std::min(ta, tb));
            t1 = std::min(t1, std::max(ta, tb));
            outside = t0 > t1;
        }
        if (outside) continue;
        if (node.count > 0) {
            test_leaf(node, ray, t_min_m, best);
            continue;
        }
        const std::uint32_t left = static_cast<std::uint32_t>(&node - nodes_.data()) + 1;
        const std::uint32_t right = node.index;
        const bool right_first = ray.direction[node.axis] < 0.0;
        stack[top++] = right_first ? left : right;  // farther child below
        stack[top++] = right_first ? right : left;
    }
    if (!best.hit()) best.distance_m = std::numeric_limits<double>::infinity();
    return best;
}

RayHit RayCaster::cast_brute_force(const Eigen::Vector3d& origin_m,
                                   const Eigen::Vector3d& direction_unit, double t_min_m,
                                   double t_max_m) const {
    RayHit best;
    best.distance_m = t_max_m;
    for (std::size_t slot = 0; slot < triangle_ids_.size(); ++slot) {
        const float* c = &corners_[9 * slot];
        double t;
        if (!intersect_ray_triangle(origin_m, direction_unit, Eigen::Vector3d(c[0], c[1], c[2]),
                                    Eigen::Vector3d(c[3], c[4], c[5]),
                                    Eigen::Vector3d(c[6], c[7], c[8]), t_min_m, best.distance_m,
                                    t)) {
            continue;
        }
        const std::int32_t id = triangle_ids_[slot];
        if (t < best.distance_m || best.triangle_id < 0 || id < best.triangle_id) {
            best.distance_m = t;
            best.triangle_id = id;
        }
    }
    if (!best.hit()) best.distance_m = std::numeric_limits<double>::infinity();
    return best;
}

}  // namespace shine
