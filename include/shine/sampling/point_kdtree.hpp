// A static k-d tree over 3-D points for the k nearest neighbours within a radius: the
// neighbourhoods behind the endpoint normals (surface_normals.hpp).
//
// The tree and its search are those of nanoflann 1.4.2's KDTreeSingleIndexAdaptor with the
// L2_Simple metric in float (which the normals used before), reproduced operation for operation:
// the same sliding-midpoint splits (the widest cell side, cut at its middle clamped to the
// points' range, nanoflann's two-pass partition), the same leaves in the same order, and the same
// walk (nearer child first, the other one pruned by nanoflann's incremental distance bound).
// Hence a query returns exactly nanoflann's neighbours in nanoflann's order, including which of
// several points at equal distance come first and which one is the k-th: normals computed from
// them are bit for bit the previous ones. What differs is the cost:
//   - the build recurses into the two halves of large nodes in parallel (TBB); every node only
//     permutes its own range of points, so the tree does not depend on the scheduling;
//   - the points are moved with the partition instead of an index array into the caller's data,
//     and stored by leaf, one array per coordinate, so that a leaf is a few contiguous cache lines
//     whose distances vectorise (nanoflann reads every point through the index, a cache miss
//     each on large sets);
//   - nodes are 16 bytes in one array, depth first, the first child next to its parent;
//   - most nodes cut at their cell's middle before looking up their points' range, which is
//     needed only when all of them lie on one side (the partition has then moved nothing);
//   - nodes of up to a few thousand points make nanoflann's swaps without its data-dependent
//     branches: passes that only count list the pairs its scans would swap;
//   - a leaf's distances use SSE2, with the same float operations in the same order, and the
//     sorted insertion into the result is a few SSE2 minima, maxima and selections;
//   - a point no nearer than the k-th distance as it is by then is not inserted (nanoflann
//     compares with the k-th as the leaf was entered, and drops such a point on insertion), and
//     a subtree already beyond it is not pushed (it would be left out when its turn came).
// "Bit for bit" assumes the default x86-64 build: with SHINE_NATIVE the compiler may fuse
// multiply-adds, differently here and in nanoflann.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace shine {

/// A point of a PointKdTree: its position and the caller's index for it.
struct IndexedPoint {
    Eigen::Vector3f position = Eigen::Vector3f::Zero();
    std::uint32_t index = 0;
};

/// A neighbour returned by PointKdTree::nearest.
struct PointNeighbor {
    /// Squared distance to the query, computed in float as (dx * dx + dy * dy) + dz * dz with
    /// d = query - position (point_distance_sq).
    float distance_sq = 0.0f;
    std::uint32_t index = 0;                             ///< IndexedPoint::index
    Eigen::Vector3f position = Eigen::Vector3f::Zero();  ///< IndexedPoint::position
};

/// The squared distance PointKdTree uses (nanoflann's L2_Simple_Adaptor), in its exact order of
/// float operations; a brute-force reference must compute it the same way.
inline float point_distance_sq(const Eigen::Vector3f& query, const Eigen::Vector3f& point) {
    const float dx = query.x() - point.x();
    const float dy = query.y() - point.y();
    const float dz = query.z() - point.z();
    return (dx * dx + dy * dy) + dz * dz;
}

/// Static k-d tree for k nearest neighbours within a radius; immutable (thread-safe) once built.
class PointKdTree {
  public:
    /// nanoflann's default leaf_max_size, which the normals used.
    static constexpr int kDefaultLeafSize = 16;
    static constexpr int kMaxLeafSize = 256;
    /// The most neighbours a query returns.
    static constexpr int kMaxNeighbors = 64;

    /// An empty tree (every query finds nothing).
    PointKdTree() = default;
    /// Builds the tree over `points` (their order is nanoflann's initial index order, and matters
    /// only for the order of equal distances) with leaves of at most `leaf_size` points; parallel
    /// and deterministic. Throws ConfigError if leaf_size is outside [1, kMaxLeafSize] and
    /// DataError for 2^32 or more points.
    explicit PointKdTree(std::vector<IndexedPoint> points, int leaf_size = kDefaultLeafSize);

    /// The at most k (at most kMaxNeighbors) nearest points with point_distance_sq(query, position)
    /// <= max_distance_sq, nearest first, written to `neighbors` (room for k); returns how many.
    /// Points at equal distance come in the order the tree walk meets them, as in nanoflann's
    /// KNNResultSet (whose search bound the previous code initialised to just above
    /// max_distance_sq). k <= 0 finds nothing.
    int nearest(const Eigen::Vector3f& query, int k, float max_distance_sq,
                PointNeighbor* neighbors) const;

    /// Number of points in the tree.
    std::size_t size() const { return index_.size(); }
    /// Index of the point stored at `slot` in [0, size()); slots are in leaf order, so queries
    /// issued in slot order walk the tree coherently (neighbouring queries share leaves).
    std::uint32_t index_at(std::size_t slot) const { return index_[slot]; }
    /// Position of the point stored at `slot`.
    Eigen::Vector3f position_at(std::size_t slot) const {
        return Eigen::Vector3f(x_[slot], y_[slot], z_[slot]);
    }

  private:
    struct Interval {
        float low, high;
    };
    using Box = std::array<Interval, 3>;
    /// Inner node: the split axis, the largest coordinate of the first child's points along it
    /// (div_low) and the smallest of the second child's (div_high); the first child is the next
    /// node, the second one `second_child` nodes further. Leaf: its slots.
    struct Node {
        float div_low = 0.0f;
        float div_high = 0.0f;
        std::uint32_t second_child_or_begin = 0;
        std::uint32_t axis_or_leaf_size = 0;  ///< axis, or kLeafFlag | number of points
    };
    static constexpr std::uint32_t kLeafFlag = 0x80000000u;
    struct Subtree {
        Box box;     ///< bounding box of the subtree's points
        int height;  ///< nodes on the longest path to a leaf
    };
    struct Search;
    struct Pending;

    Subtree build(IndexedPoint* points, std::size_t begin, std::size_t end, const Box& cell,
                  std::vector<Node>& nodes) const;
    void search(Search& s, Pending* stack, const Pending& root) const;
    void scan_leaf(Search& s, std::size_t begin, std::size_t count) const;

    int leaf_size_ = kDefaultLeafSize;
    int height_ = 0;      ///< nodes on the longest root-to-leaf path
    bool finite_ = true;  ///< all coordinates finite (the build may then take shortcuts)
    Box root_box_{};
    std::vector<Node> nodes_;
    std::vector<float> x_, y_, z_;      ///< coordinates by slot
    std::vector<std::uint32_t> index_;  ///< IndexedPoint::index by slot
};

}  // namespace shine
