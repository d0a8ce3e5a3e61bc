// Closest-hit ray casting against a triangle mesh: a bounding volume hierarchy (binned SAH) built
// once (the subtrees of its top levels as parallel TBB tasks), queried from many threads.
//
// The simulator casts 64 x 1800 rays per scan against a street of about a million triangles.
// Traversal uses float boxes (padded so rounding never culls a hit); the ray/triangle test
// (Moller-Trumbore) runs in double, so distances to float-exact geometry are exact to ~1e-9 m.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "shine/geometry/triangle_mesh.hpp"

namespace shine {

/// Result of a closest-hit query.
struct RayHit {
    double distance_m = std::numeric_limits<double>::infinity();  ///< along the unit direction
    std::int32_t triangle_id = -1;  ///< index into TriangleMesh::triangles; -1 for a miss

    bool hit() const { return triangle_id >= 0; }
};

/// Moller-Trumbore ray/triangle test, two-sided. Returns true and sets `t` (in units of
/// |direction|) if the ray origin + t * direction hits the triangle with t in [t_min, t_max].
bool intersect_ray_triangle(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                            const Eigen::Vector3d& v0, const Eigen::Vector3d& v1,
                            const Eigen::Vector3d& v2, double t_min, double t_max, double& t);

/// How RayCaster builds its BVH. Every choice gives the same tree, node for node.
struct BvhBuildOptions {
    /// A node over at least this many triangles builds its two subtrees as parallel tasks;
    /// SIZE_MAX builds the whole tree serially (the reference the tests compare against).
    std::size_t parallel_min_triangles = 32768;
};

/// Bounding volume hierarchy over a triangle mesh for closest-hit queries. Immutable after
/// construction; cast() is thread-safe.
class RayCaster {
  public:
    /// Builds the BVH (binned surface-area heuristic, at most 4 triangles per leaf). Throws
    /// ConfigError if the mesh has an out-of-range vertex index or a non-finite vertex.
    explicit RayCaster(const TriangleMesh& mesh);

    /// BVH over triangles [first_triangle, first_triangle + num_triangles) of `mesh` only (one
    /// block of a large scene, see BlockRayCaster); hits report the triangle's index in `mesh`, and
    /// ties go to the lowest such index, so blocks agree with one BVH over the whole mesh. Throws
    /// ConfigError as above, or if the range exceeds the mesh.
    RayCaster(const TriangleMesh& mesh, std::size_t first_triangle, std::size_t num_triangles);

    /// As above, built as `options` say.
    RayCaster(const TriangleMesh& mesh, std::size_t first_triangle, std::size_t num_triangles,
              const BvhBuildOptions& options);

    /// Closest hit of the ray origin_m + t * direction_unit with t in [t_min_m, t_max_m];
    /// `direction_unit` must have unit length for distance_m to be in metres.
    RayHit cast(const Eigen::Vector3d& origin_m, const Eigen::Vector3d& direction_unit,
                double t_min_m = 0.0,
                double t_max_m = std::numeric_limits<double>::infinity()) const;

    /// Same query by testing every triangle: the slow reference the BVH is checked against.
    RayHit cast_brute_force(const Eigen::Vector3d& origin_m, const Eigen::Vector3d& direction_unit,
                            double t_min_m = 0.0,
                            double t_max_m = std::numeric_limits<double>::infinity()) const;

    /// Box around all triangles (slightly padded); empty (min > max) without triangles.
    Eigen::AlignedBox3f bounds() const;

    std::size_t num_triangles() const { return triangle_ids_.size(); }
    std::size_t num_nodes() const { return nodes_.size(); }

    /// True if `other` has the same BVH: equal nodes, triangle slots and corners.
    bool same_bvh(const RayCaster& other) const;

  private:
    struct Node {
        float lower[3];
        float upper[3];
        std::uint32_t index;  ///< leaf: first triangle slot; inner: right child (left is next)
        std::uint16_t count;  ///< triangles in a leaf; 0 for an inner node
        std::uint16_t axis;   ///< split axis of an inner node
    };
    struct Ray;

    void test_leaf(const Node& node, const Ray& ray, double t_min_m, RayHit& best) const;

    std::vector<Node> nodes_;
    std::vector<float> corners_;              ///< 9 floats per triangle slot, in BVH leaf order
    std::vector<std::int32_t> triangle_ids_;  ///< original index of each triangle slot
};

}  // namespace shine
