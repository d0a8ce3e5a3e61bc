#include "shine/geometry/ray_caster.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <memory>
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

/// A node's boxes and (index, count, axis) entries in depth-first order: the left child follows
/// its parent, the right child's index is stored in the parent.
struct NodeList {
    std::vector<Box> boxes;
    std::vector<std::array<std::uint32_t, 3>> info;  // index, count, axis

    std::size_t size() const { return boxes.size(); }
};

/// What a node does with order[begin, end): become a leaf, or split at `middle` along `axis`.
struct Split {
    Box bounds;
    bool leaf = false;
    std::size_t middle = 0;
    std::uint32_t axis = 0;
};

struct Builder {
    const std::vector<Primitive>& primitives;
    std::vector<std::int32_t>& order;

    /// Decides node order[begin, end) at `depth` (partitioning `order` for a split). Throws
    /// ConfigError at the depth limit with too many triangles left for a leaf.
    Split split(std::size_t begin, std::size_t end, int depth) const {
        Split result;
        Box centroid_bounds;
        for (std::size_t i = begin; i < end; ++i) {
            result.bounds.extend(primitives[order[i]].box);
            centroid_bounds.extend(primitives[order[i]].centroid);
        }
        const Box& bounds = result.bounds;
        const std::size_t count = end - begin;
        result.leaf = true;
        if (count <= static_cast<std::size_t>(kMaxLeafSize)) return result;
        if (depth >= kMaxDepth) {
            if (count > 0xFFFF) {
                throw ConfigError(
                    "RayCaster: BVH deeper than " + std::to_string(kMaxDepth) + " levels with " +
                    std::to_string(count) +
                    " triangles left; the mesh is degenerate (coincident triangles?)");
            }
            return result;
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
                return result;
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
            return result;  // all centroids coincide
        }
        result.leaf = false;
        result.middle = middle;
        result.axis = static_cast<std::uint32_t>(axis_for_node);
        return result;
    }

    /// Appends the subtree over order[begin, end) to `out` and returns its node index there.
    std::uint32_t build(std::size_t begin, std::size_t end, int depth, NodeList& out) const {
        const auto node = static_cast<std::uint32_t>(out.size());
        const Split s = split(begin, end, depth);
        out.boxes.push_back(s.bounds);
        if (s.leaf) {
            out.info.push_back(
                {static_cast<std::uint32_t>(begin), static_cast<std::uint32_t>(end - begin), 0});
            return node;
        }
        out.info.push_back({0, 0, s.axis});
        build(begin, s.middle, depth + 1, out);
        const std::uint32_t right_child = build(s.middle, end, depth + 1, out);
        out.info[node][0] = right_child;
        return node;
    }
};

/// A subtree of the parallel build: either one inner node whose two children were built as
/// parallel tasks, or a subtree built serially (`nodes`, with indices relative to its first node).
/// The nodes come out exactly as one serial build() would make them, in the same order.
struct Part {
    NodeList nodes;
    std::unique_ptr<Part> left, right;  // set for an inner node split at the top
    std::exception_ptr error;           // what building this part threw (the build stops there)
    std::size_t size = 0;               // nodes in the whole subtree

    void build(const Builder& builder, std::size_t begin, std::size_t end, int depth,
               std::size_t parallel_min_triangles) {
        try {
            if (end - begin < parallel_min_triangles) {
                builder.build(begin, end, depth, nodes);
                size = nodes.size();
                return;
            }
            const Split s = builder.split(begin, end, depth);
            nodes.boxes.push_back(s.bounds);
            if (s.leaf) {
                nodes.info.push_back({static_cast<std::uint32_t>(begin),
                                      static_cast<std::uint32_t>(end - begin), 0});
                size = 1;
                return;
            }
            nodes.info.push_back({0, 0, s.axis});
            left = std::make_unique<Part>();
            right = std::make_unique<Part>();
            // The two halves of `order` are disjoint, so the tasks never touch the same slot.
            tbb::parallel_invoke(
                [&] { left->build(builder, begin, s.middle, depth + 1, parallel_min_triangles); },
                [&] { right->build(builder, s.middle, end, depth + 1, parallel_min_triangles); });
            size = 1 + left->size + right->size;
        } catch (...) {
            error = std::current_exception();
        }
    }

    /// The first error in depth-first order, which is the one a serial build stops at.
    std::exception_ptr first_error() const {
        if (error) return error;
        for (const Part* child : {left.get(), right.get()}) {
            if (!child) continue;
            if (std::exception_ptr e = child->first_error()) return e;
        }
        return nullptr;
    }

    /// Writes the subtree's nodes to out[first, first + size), child indices offset by `first`.
    template <class Write>
    void emit(std::uint32_t first, const Write& write) const {
        if (!left) {
            for (std::size_t i = 0; i < nodes.size(); ++i) {
                std::array<std::uint32_t, 3> info = nodes.info[i];
                if (info[1] == 0) info[0] += first;  // inner node: right child index
                write(first + static_cast<std::uint32_t>(i), nodes.boxes[i], info);
            }
            return;
        }
        const auto right_first = static_cast<std::uint32_t>(first + 1 + left->size);
        write(first, nodes.boxes[0], {right_first, 0, nodes.info[0][2]});
        tbb::parallel_invoke([&] { left->emit(first + 1, write); },
                             [&] { right->emit(right_first, write); });
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
                     std::size_t num_triangles)
    : RayCaster(mesh, first_triangle, num_triangles, BvhBuildOptions{}) {}

RayCaster::RayCaster(const TriangleMesh& mesh, std::size_t first_triangle,
                     std::size_t num_triangles, const BvhBuildOptions& options) {
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
    // Every triangle is checked first (in order, so the first bad one is named), then the
    // primitives are made in parallel.
    for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector3i& t = mesh.triangles[first_triangle + i];
        for (int k = 0; k < 3; ++k) {
            if (t[k] < 0 || t[k] >= n_vertices) {
                throw ConfigError("RayCaster: triangle " + std::to_string(first_triangle + i) +
                                  " has vertex index " + std::to_string(t[k]) +
                                  " but the mesh has " + std::to_string(n_vertices) + " vertices");
            }
            if (!mesh.vertices[t[k]].allFinite()) {
                throw ConfigError("RayCaster: vertex " + std::to_string(t[k]) + " is not finite");
            }
        }
    }
    if (n == 0) return;
    constexpr std::size_t kGrain = 16384;
    std::vector<Primitive> primitives(n);
    std::vector<std::int32_t> order(n);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, kGrain),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              const Eigen::Vector3i& t = mesh.triangles[first_triangle + i];
                              Primitive& p = primitives[i];
                              for (int k = 0; k < 3; ++k) p.box.extend(mesh.vertices[t[k]]);
                              for (int a = 0; a < 3; ++a) {
                                  p.box.lower[a] = pad(p.box.lower[a], -1.0f);
                                  p.box.upper[a] = pad(p.box.upper[a], 1.0f);
                              }
                              p.centroid = 0.5f * (p.box.lower + p.box.upper);
                              order[i] = static_cast<std::int32_t>(i);
                          }
                      });

    const Builder builder{primitives, order};
    Part root;
    root.build(builder, 0, n, 0, options.parallel_min_triangles);
    if (std::exception_ptr error = root.first_error()) std::rethrow_exception(error);

    nodes_.resize(root.size);
    root.emit(0, [&](std::uint32_t i, const Box& box, const std::array<std::uint32_t, 3>& info) {
        Node& node = nodes_[i];
        for (int a = 0; a < 3; ++a) {
            node.lower[a] = box.lower[a];
            node.upper[a] = box.upper[a];
        }
        node.index = info[0];
        node.count = static_cast<std::uint16_t>(info[1]);
        node.axis = static_cast<std::uint16_t>(info[2]);
    });
    // Slots name triangles by their index in the whole mesh.
    corners_.resize(9 * n);
    triangle_ids_.resize(n);
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, kGrain),
        [&](const tbb::blocked_range<std::size_t>& range) {
            for (std::size_t slot = range.begin(); slot != range.end(); ++slot) {
                const Eigen::Vector3i& t = mesh.triangles[first_triangle + order[slot]];
                for (int k = 0; k < 3; ++k) {
                    for (int a = 0; a < 3; ++a) {
                        corners_[9 * slot + 3 * k + a] = mesh.vertices[t[k]][a];
                    }
                }
                triangle_ids_[slot] = static_cast<std::int32_t>(first_triangle) + order[slot];
            }
        });
}

bool RayCaster::same_bvh(const RayCaster& other) const {
    if (nodes_.size() != other.nodes_.size() || corners_ != other.corners_ ||
        triangle_ids_ != other.triangle_ids_) {
        return false;
    }
    for (std::size_t i = 0; i < nodes_.size(); ++i) {
        const Node& a = nodes_[i];
        const Node& b = other.nodes_[i];
        if (!std::equal(a.lower, a.lower + 3, b.lower) ||
            !std::equal(a.upper, a.upper + 3, b.upper) || a.index != b.index ||
            a.count != b.count || a.axis != b.axis) {
            return false;
        }
    }
    return true;
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
