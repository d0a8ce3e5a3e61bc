// The k-d tree behind the endpoint normals (point_kdtree.hpp) against nanoflann 1.4.2, whose tree
// and search it reproduces (same neighbours in the same order, equal distances included; the same
// order of the points in the leaves), against a brute-force search (same distances) and against an
// exhaustive walk that prunes nothing (every point, equal distances in the walk's order: the first
// k within the radius); estimate_ray_normals against the nanoflann-based implementation it
// replaced (bit for bit) and against the same PCA over brute-force neighbours.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <nanoflann.hpp>
#include <random>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/sampling/point_kdtree.hpp"
#include "shine/sampling/ray_set.hpp"
#include "shine/sampling/surface_normals.hpp"

using namespace shine;

namespace {

constexpr int kMaxNeighbors = PointKdTree::kMaxNeighbors;

/// nanoflann's view of a point set (the positions, by index).
struct PointCloud {
    const std::vector<Eigen::Vector3f>& points;
    std::size_t kdtree_get_point_count() const { return points.size(); }
    float kdtree_get_pt(std::uint32_t i, std::size_t axis) const {
        return points[i][static_cast<Eigen::Index>(axis)];
    }
    template <class BoundingBox>
    bool kdtree_get_bbox(BoundingBox& /*unused*/) const {
        return false;
    }
};
using NanoflannTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PointCloud>, PointCloud,
                                        3, std::uint32_t>;

/// The reference the tree reproduces: nanoflann's KNNResultSet with its worst distance set to
/// just above max_distance_sq, as the normals did before.
std::vector<PointNeighbor> nanoflann_nearest(const NanoflannTree& tree,
                                             const std::vector<Eigen::Vector3f>& points,
                                             const Eigen::Vector3f& query, int k,
                                             float max_distance_sq) {
    std::uint32_t index[kMaxNeighbors];
    float distance_sq[kMaxNeighbors];
    nanoflann::KNNResultSet<float, std::uint32_t> result(static_cast<std::size_t>(k));
    result.init(index, distance_sq);
    distance_sq[k - 1] = std::nextafter(max_distance_sq, std::numeric_limits<float>::infinity());
    tree.findNeighbors(result, query.data(), nanoflann::SearchParams());
    std::vector<PointNeighbor> found;
    for (std::size_t i = 0; i < result.size(); ++i) {
        found.push_back({distance_sq[i], index[i], points[index[i]]});
    }
    return found;
}

/// Every point within the radius, nearest first, the first k: the distances any correct search
/// returns (which of several points at equal distance it returns is the tree's choice).
std::vector<float> brute_force_distances(const std::vector<Eigen::Vector3f>& points,
                                         const Eigen::Vector3f& query, int k,
                                         float max_distance_sq) {
    std::vector<float> all;
    for (const Eigen::Vector3f& p : points) {
        const float d = point_distance_sq(query, p);
        if (d <= max_distance_sq) all.push_back(d);
    }
    const std::size_t kept = std::min(all.size(), static_cast<std::size_t>(k));
    std::partial_sort(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(kept), all.end());
    all.resize(kept);
    return all;
}

std::vector<IndexedPoint> indexed(const std::vector<Eigen::Vector3f>& positions) {
    std::vector<IndexedPoint> points;
    for (std::size_t i = 0; i < positions.size(); ++i) {
        points.push_back({positions[i], static_cast<std::uint32_t>(i)});
    }
    return points;
}

struct Mismatches {
    int nanoflann = 0;    ///< queries whose neighbours (index, distance, order) differ
    int brute_force = 0;  ///< queries whose distances differ from the brute force's
    int tied = 0;         ///< queries with equal distances among their neighbours
};

/// A point set with both trees over it.
struct Trees {
    const std::vector<Eigen::Vector3f>& points;
    PointKdTree tree;
    PointCloud cloud;
    NanoflannTree reference;

    Trees(const std::vector<Eigen::Vector3f>& points_in, int leaf_size)
        : points(points_in),
          tree(indexed(points_in), leaf_size),
          cloud{points_in},
          reference(
              3, cloud,
              nanoflann::KDTreeSingleIndexAdaptorParams(static_cast<std::size_t>(leaf_size))) {
        reference.buildIndex();
    }
};

/// Runs every query through PointKdTree, nanoflann and the brute force.
Mismatches compare(const Trees& trees, const std::vector<Eigen::Vector3f>& queries, int k,
                   float max_distance_sq) {
    Mismatches m;
    PointNeighbor found[kMaxNeighbors];
    for (const Eigen::Vector3f& q : queries) {
        const int n = trees.tree.nearest(q, k, max_distance_sq, found);
        const std::vector<PointNeighbor> expected =
            nanoflann_nearest(trees.reference, trees.points, q, k, max_distance_sq);
        bool same = n == static_cast<int>(expected.size());
        for (int i = 0; same && i < n; ++i) {
            same = found[i].index == expected[i].index &&
                   found[i].distance_sq == expected[i].distance_sq &&
                   found[i].position == expected[i].position;
        }
        m.nanoflann += !same;
        const std::vector<float> distances =
            brute_force_distances(trees.points, q, k, max_distance_sq);
        bool same_distances = n == static_cast<int>(distances.size());
        for (int i = 0; same_distances && i < n; ++i) {
            same_distances = found[i].distance_sq == distances[static_cast<std::size_t>(i)] &&
                             found[i].distance_sq == point_distance_sq(q, found[i].position);
        }
        m.brute_force += !same_distances;
        for (int i = 1; i < n; ++i) {
            if (found[i].distance_sq == found[i - 1].distance_sq) {
                ++m.tied;
                break;
            }
        }
    }
    return m;
}

Mismatches compare(const std::vector<Eigen::Vector3f>& points,
                   const std::vector<Eigen::Vector3f>& queries, int leaf_size, int k,
                   float max_distance_sq) {
    return compare(Trees(points, leaf_size), queries, k, max_distance_sq);
}

std::vector<Eigen::Vector3f> random_points(int count, float extent_m, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-extent_m, extent_m);
    std::vector<Eigen::Vector3f> points;
    for (int i = 0; i < count; ++i) points.emplace_back(u(rng), u(rng), u(rng));
    return points;
}

/// A plane z = 0 on a 0.125 m grid and a line along x above it: coordinates exact in float, so
/// distances repeat exactly (four neighbours at 0.125 m, four at 0.125 * sqrt(2), ...), and many
/// points share a coordinate with the split values.
std::vector<Eigen::Vector3f> plane_and_line() {
    std::vector<Eigen::Vector3f> points;
    for (int i = -24; i <= 24; ++i) {
        for (int j = -24; j <= 24; ++j) points.emplace_back(0.125f * i, 0.125f * j, 0.0f);
    }
    for (int i = -40; i <= 40; ++i) points.emplace_back(0.0625f * i, 1.0f, 0.75f);
    return points;
}

/// The previous estimate_ray_normals (nanoflann 1.4.2 over all endpoints), verbatim but for names.
struct EndpointCloud {
    const RaySet& rays;
    std::size_t kdtree_get_point_count() const { return rays.num_rays(); }
    float kdtree_get_pt(std::uint32_t ray, std::size_t axis) const {
        return rays.endpoint(ray)[static_cast<Eigen::Index>(axis)];
    }
    template <class BoundingBox>
    bool kdtree_get_bbox(BoundingBox& /*unused*/) const {
        return false;
    }
};
using EndpointTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, EndpointCloud>,
                                        EndpointCloud, 3, std::uint32_t>;

std::vector<Eigen::Vector3f> nanoflann_normals(const RaySet& rays, const NormalConfig& config,
                                               std::size_t ray_begin, std::size_t ray_end) {
    const std::size_t n = rays.num_rays();
    std::vector<Eigen::Vector3f> normals(n, Eigen::Vector3f::Zero());
    ray_end = std::min(ray_end, n);
    if (n < 3 || ray_begin >= ray_end) return normals;
    const EndpointCloud cloud{rays};
    EndpointTree tree(3, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    tree.buildIndex();
    const int k = std::clamp(config.neighbors, 3, kMaxNeighbors);
    const float max_radius_sq = config.max_radius_m * config.max_radius_m;
    const float search_bound_sq =
        std::nextafter(max_radius_sq, std::numeric_limits<float>::infinity());
    std::uint32_t index[kMaxNeighbors];
    float distance_sq[kMaxNeighbors];
    for (std::size_t ray = ray_begin; ray < ray_end; ++ray) {
        const Eigen::Vector3f& p = rays.endpoint(ray);
        nanoflann::KNNResultSet<float, std::uint32_t> result(static_cast<std::size_t>(k));
        result.init(index, distance_sq);
        distance_sq[k - 1] = search_bound_sq;
        tree.findNeighbors(result, p.data(), nanoflann::SearchParams());
        const std::size_t found = result.size();
        std::uint32_t kept[kMaxNeighbors];
        int used = 0;
        for (std::size_t i = 0; i < found; ++i) {
            if (distance_sq[i] <= max_radius_sq) kept[used++] = index[i];
        }
        normals[ray] = fit_plane_normal(
            used, [&](int i) -> const Eigen::Vector3f& { return rays.endpoint(kept[i]); }, p,
            rays.origin_of_ray(ray), config);
    }
    return normals;
}

/// Slow reference without any tree: the same PCA over the brute-force k nearest (ties to the
/// smaller index); equal to the others where no two neighbours are at equal distance.
std::vector<Eigen::Vector3f> brute_force_normals(const RaySet& rays, const NormalConfig& config,
                                                 std::size_t ray_begin, std::size_t ray_end) {
    std::vector<Eigen::Vector3f> normals(rays.num_rays(), Eigen::Vector3f::Zero());
    const int k = std::clamp(config.neighbors, 3, kMaxNeighbors);
    const float max_radius_sq = config.max_radius_m * config.max_radius_m;
    for (std::size_t ray = ray_begin; ray < ray_end; ++ray) {
        const Eigen::Vector3f& p = rays.endpoint(ray);
        std::vector<std::pair<float, std::size_t>> near;
        for (std::size_t other = 0; other < rays.num_rays(); ++other) {
            const float d = point_distance_sq(p, rays.endpoint(other));
            if (d <= max_radius_sq) near.emplace_back(d, other);
        }
        std::sort(near.begin(), near.end());
        if (near.size() > static_cast<std::size_t>(k)) near.resize(static_cast<std::size_t>(k));
        normals[ray] = fit_plane_normal(
            static_cast<int>(near.size()),
            [&](int i) -> const Eigen::Vector3f& { return rays.endpoint(near[i].second); }, p,
            rays.origin_of_ray(ray), config);
    }
    return normals;
}

/// Number of rays whose normals differ in any bit.
int count_different(const std::vector<Eigen::Vector3f>& a, const std::vector<Eigen::Vector3f>& b) {
    EXPECT_EQ(a.size(), b.size());
    int different = 0;
    for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
        different += std::memcmp(a[i].data(), b[i].data(), 3 * sizeof(float)) != 0;
    }
    return different;
}

/// Ground and a wall seen from a sensor at `origin`: a coarse 32-beam sweep (200 azimuths), as in
/// the kernel benchmark.
std::vector<Eigen::Vector3f> ground_and_wall_sweep(const Eigen::Vector3f& origin) {
    std::vector<Eigen::Vector3f> endpoints;
    for (int beam = 0; beam < 32; ++beam) {
        const float elevation = (-25.0f + 27.0f * beam / 31.0f) * float(M_PI) / 180.0f;
        for (int a = 0; a < 200; ++a) {
            const float azimuth = 2.0f * float(M_PI) * (a + 0.3f) / 200.0f;
            const Eigen::Vector3f d(std::cos(elevation) * std::cos(azimuth),
                                    std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
            float t = 30.0f;
            if (d.z() < 0.0f) t = std::min(t, origin.z() / -d.z());
            if (d.x() > 0.0f) t = std::min(t, (12.0f - origin.x()) / d.x());
            if (t < 30.0f) endpoints.push_back(origin + t * d);
        }
    }
    return endpoints;
}

/// The reference for the order of equal distances, without any pruning: nanoflann's search with
/// room for every point visits every leaf (nearer child first) and keeps every point, nearest
/// first and, at equal distances, in the order the walk met them. Its first k within a radius
/// are what a search must return. The distances are checked against a brute force.
std::vector<PointNeighbor> exhaustive_walk(const Trees& trees, const Eigen::Vector3f& query) {
    const std::size_t n = trees.points.size();
    std::vector<std::uint32_t> index(n);
    std::vector<float> distance_sq(n);
    nanoflann::KNNResultSet<float, std::uint32_t> result(n);
    result.init(index.data(), distance_sq.data());
    trees.reference.findNeighbors(result, query.data(), nanoflann::SearchParams());
    EXPECT_EQ(result.size(), n);
    std::vector<float> brute_force;
    for (const Eigen::Vector3f& p : trees.points)
        brute_force.push_back(point_distance_sq(query, p));
    std::sort(brute_force.begin(), brute_force.end());
    EXPECT_EQ(distance_sq, brute_force);
    std::vector<PointNeighbor> walk;
    for (std::size_t i = 0; i < n; ++i) {
        walk.push_back({distance_sq[i], index[i], trees.points[index[i]]});
    }
    return walk;
}

/// What compare_with_exhaustive_walk covered.
struct WalkComparison {
    int different = 0;     ///< searches whose neighbours (index, distance, order) differ
    int tied = 0;          ///< searches with distinct points at equal distance among the neighbours
    int cut_in_a_tie = 0;  ///< searches whose k-th neighbour ties with a point left out
    int fewer_than_k = 0;  ///< searches with fewer than k points within the radius
};

/// PointKdTree::nearest for every query, k and radius against the first k of the exhaustive walk
/// within the radius.
WalkComparison compare_with_exhaustive_walk(const Trees& trees,
                                            const std::vector<Eigen::Vector3f>& queries,
                                            const std::vector<int>& ks,
                                            const std::vector<float>& radii_m) {
    WalkComparison c;
    PointNeighbor found[kMaxNeighbors];
    for (const Eigen::Vector3f& q : queries) {
        const std::vector<PointNeighbor> walk = exhaustive_walk(trees, q);
        for (const int k : ks) {
            for (const float radius_m : radii_m) {
                const float max_distance_sq = radius_m * radius_m;
                const int n = trees.tree.nearest(q, k, max_distance_sq, found);
                int within = 0;
                while (within < static_cast<int>(walk.size()) &&
                       walk[static_cast<std::size_t>(within)].distance_sq <= max_distance_sq) {
                    ++within;
                }
                const int kept = std::min(within, k);
                bool same = n == kept;
                for (int i = 0; same && i < n; ++i) {
                    const PointNeighbor& expected = walk[static_cast<std::size_t>(i)];
                    same = found[i].index == expected.index &&
                           found[i].distance_sq == expected.distance_sq;
                }
                c.different += !same;
                if (!same) {
                    ADD_FAILURE() << "query " << q.transpose() << ", k " << k << ", radius "
                                  << radius_m;
                }
                for (int i = 1; i < kept; ++i) {
                    const PointNeighbor& a = walk[static_cast<std::size_t>(i - 1)];
                    const PointNeighbor& b = walk[static_cast<std::size_t>(i)];
                    if (a.distance_sq == b.distance_sq && a.position != b.position) {
                        ++c.tied;
                        break;
                    }
                }
                c.cut_in_a_tie +=
                    within > k && walk[static_cast<std::size_t>(k)].distance_sq ==
                                      walk[static_cast<std::size_t>(k - 1)].distance_sq;
                c.fewer_than_k += within < k;
            }
        }
    }
    return c;
}

/// Three sweeps over ground and a wall from sensors 1 m apart (about 19 000 endpoints in scan
/// order, so the tree's large nodes hold long runs on one side of their cut), and a copy of every
/// 50th endpoint at its end (points at equal positions).
std::vector<Eigen::Vector3f> three_sweeps_with_copies() {
    std::vector<Eigen::Vector3f> points;
    for (int s = 0; s < 3; ++s) {
        const Eigen::Vector3f origin(-1.0f * s, 0.3f * s, 1.7f);
        for (const Eigen::Vector3f& p : ground_and_wall_sweep(origin)) points.push_back(p);
    }
    const std::size_t swept = points.size();
    for (std::size_t i = 0; i < swept; i += 50) points.push_back(points[i]);
    return points;
}
}  // namespace

TEST(PointKdTree, EqualsNanoflannAndBruteForceOnRandomPoints) {
    const std::vector<Eigen::Vector3f> points = random_points(4000, 2.0f, 11);
    std::vector<Eigen::Vector3f> queries = random_points(300, 2.5f, 12);  // some outside the box
    for (int i = 0; i < 300; ++i) queries.push_back(points[13 * i]);      // the points themselves
    for (int leaf_size : {1, 2, 16, 64, PointKdTree::kMaxLeafSize}) {
        const Trees trees(points, leaf_size);
        for (int k : {1, 5, 16, kMaxNeighbors}) {
            for (float radius_m : {0.05f, 0.3f, 1.0f, std::numeric_limits<float>::infinity()}) {
                const Mismatches m = compare(trees, queries, k, radius_m * radius_m);
                EXPECT_EQ(m.nanoflann, 0)
                    << "leaf size " << leaf_size << ", k " << k << ", radius " << radius_m;
                EXPECT_EQ(m.brute_force, 0)
                    << "leaf size " << leaf_size << ", k " << k << ", radius " << radius_m;
            }
        }
    }
}

TEST(PointKdTree, EqualsNanoflannWithTiesAndTheRadiusBound) {
    // Exact grid coordinates: many equal distances, so the k-th neighbour is often one of several
    // at the same distance (which one is the tree walk's order), and the radius falls exactly on
    // grid distances.
    const std::vector<Eigen::Vector3f> points = plane_and_line();
    std::vector<Eigen::Vector3f> queries;
    for (std::size_t i = 0; i < points.size(); i += 7) queries.push_back(points[i]);
    queries.emplace_back(0.0625f, 0.0625f, 0.0f);  // between four grid points, equally far
    queries.emplace_back(0.0f, 1.0f, 0.375f);      // halfway between the plane and the line
    int tied = 0;
    for (int leaf_size : {1, 4, 16}) {
        const Trees trees(points, leaf_size);
        for (int k : {1, 4, 5, 16, 17, kMaxNeighbors}) {
            for (float radius_m : {0.125f, 0.25f, 0.5f, 1.0f}) {
                const Mismatches m = compare(trees, queries, k, radius_m * radius_m);
                EXPECT_EQ(m.nanoflann, 0)
                    << "leaf size " << leaf_size << ", k " << k << ", radius " << radius_m;
                EXPECT_EQ(m.brute_force, 0)
                    << "leaf size " << leaf_size << ", k " << k << ", radius " << radius_m;
                tied += m.tied;
            }
        }
    }
    EXPECT_GT(tied, 1000);  // the fixture does exercise ties

    // Analytically: around a grid point, the points within 0.25 m (bound included) are itself,
    // four at 0.125 m, four at 0.177 m and four at exactly 0.25 m.
    const PointKdTree tree(indexed(points));
    PointNeighbor found[kMaxNeighbors];
    const Eigen::Vector3f grid_point(0.5f, -0.5f, 0.0f);
    EXPECT_EQ(tree.nearest(grid_point, kMaxNeighbors, 0.25f * 0.25f, found), 13);
    EXPECT_EQ(found[12].distance_sq, 0.0625f);
    EXPECT_EQ(tree.nearest(grid_point, kMaxNeighbors, std::nextafter(0.0625f, 0.0f), found), 9);
    EXPECT_EQ(tree.nearest(grid_point, 3, 1.0f, found), 3);
    EXPECT_EQ(found[0].distance_sq, 0.0f);
    EXPECT_EQ(found[0].position, grid_point);
    EXPECT_EQ(found[2].distance_sq, 0.125f * 0.125f);
}

TEST(PointKdTree, NeighboursAreTheFirstKOfTheExhaustiveWalk) {
    // The grid: equal distances everywhere, the radii fall exactly on grid distances; queries on
    // grid points, between four of them, and far from every point (nothing within the radius).
    const std::vector<Eigen::Vector3f> grid = plane_and_line();
    std::vector<Eigen::Vector3f> grid_queries;
    for (std::size_t i = 0; i < grid.size(); i += 11) grid_queries.push_back(grid[i]);
    grid_queries.emplace_back(0.0625f, 0.0625f, 0.0f);
    grid_queries.emplace_back(0.0f, 1.0f, 0.375f);
    grid_queries.emplace_back(40.0f, 0.0f, 0.0f);
    WalkComparison grid_total;
    for (int leaf_size : {4, 16}) {
        const WalkComparison c =
            compare_with_exhaustive_walk(Trees(grid, leaf_size), grid_queries,
                                         {1, 5, 16, 17, kMaxNeighbors}, {0.125f, 0.25f, 1.0f});
        EXPECT_EQ(c.different, 0) << "leaf size " << leaf_size;
        grid_total.tied += c.tied;
        grid_total.cut_in_a_tie += c.cut_in_a_tie;
        grid_total.fewer_than_k += c.fewer_than_k;
    }
    // Measured: 5456 of the 6870 searches with distinct points at equal distance among their
    // neighbours, 1360 cut in a tie, 2814 with fewer than k points within the radius.
    EXPECT_GT(grid_total.tied, 2500);
    EXPECT_GT(grid_total.cut_in_a_tie, 650);
    EXPECT_GT(grid_total.fewer_than_k, 1400);

    // The sweeps, with copies: nodes of every size, equal distances at equal positions.
    const std::vector<Eigen::Vector3f> sweeps = three_sweeps_with_copies();
    std::vector<Eigen::Vector3f> sweep_queries;
    for (std::size_t i = 0; i < sweeps.size(); i += 97) sweep_queries.push_back(sweeps[i]);
    const WalkComparison c = compare_with_exhaustive_walk(
        Trees(sweeps, PointKdTree::kDefaultLeafSize), sweep_queries, {5, 16, 17}, {0.3f, 1.0f});
    EXPECT_EQ(c.different, 0);
    EXPECT_GT(c.cut_in_a_tie, 5);  // a copy and its original at the k-th distance (measured: 15)
}

TEST(PointKdTree, LeafOrderIsNanoflannsOnLargeSets) {
    // The order of the points in the leaves (which decides the order of equal distances) against
    // nanoflann's index array, on sets whose nodes take both of the build's partitions (small
    // nodes by counting passes, large ones by nanoflann's scans): the sweeps with copies, and a
    // large grid, whose coordinates often fall on the cuts.
    std::vector<Eigen::Vector3f> large_grid;
    for (int i = -60; i <= 60; ++i) {
        for (int j = -60; j <= 60; ++j) large_grid.emplace_back(0.125f * i, 0.125f * j, 0.0f);
    }
    for (int i = -100; i <= 100; ++i) large_grid.emplace_back(0.0625f * i, 1.0f, 0.75f);
    for (const std::vector<Eigen::Vector3f>& points : {three_sweeps_with_copies(), large_grid}) {
        for (int leaf_size : {1, 4, 16, 64}) {
            const Trees trees(points, leaf_size);
            ASSERT_EQ(trees.tree.size(), trees.reference.vAcc.size());
            int different = 0;
            for (std::size_t slot = 0; slot < trees.tree.size(); ++slot) {
                different += trees.tree.index_at(slot) != trees.reference.vAcc[slot];
            }
            EXPECT_EQ(different, 0) << points.size() << " points, leaf size " << leaf_size;
        }
    }
}

TEST(PointKdTree, DuplicatesAndNonFinitePointsAsNanoflann) {
    // 40 copies of one point, a few others, and points with NaN and infinite coordinates (which
    // no query finds, but which shape nanoflann's tree: the copy must shape it the same way).
    std::vector<Eigen::Vector3f> points;
    for (int i = 0; i < 40; ++i) points.emplace_back(1.0f, 2.0f, 3.0f);
    for (const Eigen::Vector3f& p : random_points(200, 3.0f, 5)) points.push_back(p);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    points.emplace_back(1.0f, nan, 3.0f);
    points.emplace_back(-inf, 0.0f, 0.0f);
    std::vector<Eigen::Vector3f> queries = {Eigen::Vector3f(1.0f, 2.0f, 3.0f),
                                            Eigen::Vector3f(1.0f, 2.0f, 3.2f)};
    for (const Eigen::Vector3f& q : random_points(50, 3.0f, 6)) queries.push_back(q);
    for (int k : {5, 16, kMaxNeighbors}) {
        for (int leaf_size : {4, 16}) {
            EXPECT_EQ(compare(points, queries, leaf_size, k, 1.0f).nanoflann, 0);
        }
    }
    // NaN first: nanoflann's bounding box starts from the first point.
    std::rotate(points.begin(), points.end() - 2, points.end());
    EXPECT_EQ(compare(points, queries, 16, 16, 1.0f).nanoflann, 0);
}

TEST(PointKdTree, SmallAndEmptySetsAndInvalidInput) {
    PointNeighbor found[kMaxNeighbors];
    EXPECT_EQ(PointKdTree().nearest(Eigen::Vector3f::Zero(), 5, 1.0f, found), 0);
    EXPECT_EQ(
        PointKdTree(std::vector<IndexedPoint>{}).nearest(Eigen::Vector3f::Zero(), 5, 1.0f, found),
        0);
    for (int n = 1; n <= 5; ++n) {
        const std::vector<Eigen::Vector3f> points = random_points(n, 1.0f, 20 + n);
        for (int leaf_size : {1, 2, 16}) {
            const Mismatches m = compare(points, random_points(20, 1.0f, 30), leaf_size, 3, 1.0f);
            EXPECT_EQ(m.nanoflann, 0);
            EXPECT_EQ(m.brute_force, 0);
        }
        EXPECT_EQ(PointKdTree(indexed(points)).nearest(Eigen::Vector3f::Zero(), 0, 1.0f, found), 0);
    }
    const std::vector<IndexedPoint> points = indexed(random_points(100, 1.0f, 40));
    EXPECT_THROW(PointKdTree(points, 0), ConfigError);
    EXPECT_THROW(PointKdTree(points, PointKdTree::kMaxLeafSize + 1), ConfigError);
}

TEST(SurfaceNormalsIndex, NormalsEqualThePreviousImplementationBitForBit) {
    // Three sweeps over ground and a wall from sensors 1 m apart, plus a plane and a line whose
    // exact grid makes many neighbours tie.
    RaySet rays;
    for (int s = 0; s < 3; ++s) {
        const Eigen::Vector3f origin(-1.0f * s, 0.3f * s, 1.7f);
        rays.add_scan(origin, ground_and_wall_sweep(origin));
    }
    rays.add_scan(Eigen::Vector3f(0.0f, 0.0f, 5.0f), plane_and_line());
    const NormalConfig config;
    const std::vector<Eigen::Vector3f> normals = estimate_ray_normals(rays, config);
    EXPECT_EQ(count_different(normals, nanoflann_normals(rays, config, 0, rays.num_rays())), 0);
    int with_normal = 0;
    for (const Eigen::Vector3f& n : normals) with_normal += n.squaredNorm() > 0.5f;
    EXPECT_GT(with_normal, static_cast<int>(rays.num_rays()) / 2);

    // Without a tree at all: wherever a ray's k + 1 nearest endpoints are at distinct distances
    // (the set and the order are then unique), the brute force agrees too. Float distances of
    // distinct points do coincide now and then, so such rays are left out, and counted.
    const std::vector<Eigen::Vector3f> brute_force =
        brute_force_normals(rays, config, 0, rays.num_rays());
    std::vector<IndexedPoint> endpoints;
    for (std::size_t r = 0; r < rays.num_rays(); ++r) {
        endpoints.push_back({rays.endpoint(r), static_cast<std::uint32_t>(r)});
    }
    const PointKdTree tree(endpoints);
    const float max_radius_sq = config.max_radius_m * config.max_radius_m;
    PointNeighbor found[kMaxNeighbors];
    int compared = 0, different = 0;
    for (std::size_t r = 0; r < rays.num_rays(); ++r) {
        const int n = tree.nearest(rays.endpoint(r), config.neighbors + 1, max_radius_sq, found);
        bool distinct = true;
        for (int i = 1; i < n; ++i)
            distinct = distinct && found[i].distance_sq != found[i - 1].distance_sq;
        if (!distinct) continue;
        ++compared;
        different += std::memcmp(normals[r].data(), brute_force[r].data(), 3 * sizeof(float)) != 0;
    }
    EXPECT_EQ(different, 0);
    EXPECT_GT(compared, static_cast<int>(rays.num_rays()) * 3 / 4);  // the grid's rays tie
}

TEST(SurfaceNormalsIndex, RangeOfRaysUsesEveryEndpoint) {
    // Incremental mode: normals of the last scan only, among all scans' endpoints.
    RaySet rays;
    for (int s = 0; s < 4; ++s) {
        const Eigen::Vector3f origin(-2.0f * s, 0.5f * s, 1.7f);
        rays.add_scan(origin, ground_and_wall_sweep(origin));
    }
    // One query whose only neighbours are four endpoints of an earlier scan at exactly the radius
    // (1 m), and one above it just beyond the radius: with them five points on the plane z = 20
    // give a normal; without one of them there would be too few, and with the one above the
    // neighbourhood would not be planar.
    rays.add_scan(Eigen::Vector3f(50.0f, 50.0f, 30.0f),
                  {Eigen::Vector3f(51.0f, 50.0f, 20.0f), Eigen::Vector3f(49.0f, 50.0f, 20.0f),
                   Eigen::Vector3f(50.0f, 51.0f, 20.0f), Eigen::Vector3f(50.0f, 49.0f, 20.0f),
                   Eigen::Vector3f(50.0f, 50.0f, std::nextafter(21.0f, 30.0f)),
                   Eigen::Vector3f(80.0f, -60.0f, 5.0f)});
    const Eigen::Vector3f origin(0.5f, 1.0f, 1.7f);
    std::vector<Eigen::Vector3f> last = ground_and_wall_sweep(origin);
    last.emplace_back(50.0f, 50.0f, 20.0f);
    rays.add_scan(origin, last);
    const std::size_t begin = rays.first_ray(5);
    const std::size_t end = rays.num_rays();
    const NormalConfig config;
    const std::vector<Eigen::Vector3f> normals = estimate_ray_normals(rays, config, begin, end);
    EXPECT_EQ(count_different(normals, nanoflann_normals(rays, config, begin, end)), 0);
    for (std::size_t r = 0; r < begin; ++r) EXPECT_EQ(normals[r], Eigen::Vector3f::Zero());
    const Eigen::Vector3f lonely = normals[end - 1];  // seen from below: the normal points down
    EXPECT_LT((lonely + Eigen::Vector3f::UnitZ()).norm(), 1e-6f) << lonely.transpose();

    // A range in the middle, one past the end, and an empty one.
    const std::size_t mid_begin = rays.first_ray(1), mid_end = rays.first_ray(2);
    EXPECT_EQ(count_different(estimate_ray_normals(rays, config, mid_begin, mid_end),
                              nanoflann_normals(rays, config, mid_begin, mid_end)),
              0);
    EXPECT_EQ(count_different(estimate_ray_normals(rays, config, begin, end + 100), normals), 0);
    for (const Eigen::Vector3f& n : estimate_ray_normals(rays, config, end, end)) {
        EXPECT_EQ(n, Eigen::Vector3f::Zero());
    }
}
