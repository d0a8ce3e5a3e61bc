// Dynamic objects (dynamic_objects.hpp): the votes of part of a compact object spread to all of
// it, never to the ground under it, to a structure wider than a car, to an object too few of
// whose points are dynamic, or to a separate object next to it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/core/random.hpp"
#include "shine/sampling/dynamic_objects.hpp"

using namespace shine;

namespace {

/// A scan of one flat ground (20 x 20 m at z = 0, 0.2 m apart) and boxes' surfaces (0.1 m
/// apart); `first_of` gives where each box's points start.
struct Scene {
    std::vector<Eigen::Vector3f> points;
    std::vector<std::size_t> first_of;
    std::size_t ground_points = 0;
};

void add_box(Scene& scene, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) {
    scene.first_of.push_back(scene.points.size());
    const float step = 0.1f;
    for (float x = lo.x(); x <= hi.x(); x += step) {
        for (float y = lo.y(); y <= hi.y(); y += step) {
            scene.points.emplace_back(x, y, hi.z());  // top
        }
        for (float z = lo.z(); z <= hi.z(); z += step) {
            scene.points.emplace_back(x, lo.y(), z);  // sides
            scene.points.emplace_back(x, hi.y(), z);
        }
    }
    for (float y = lo.y(); y <= hi.y(); y += step) {
        for (float z = lo.z(); z <= hi.z(); z += step) {
            scene.points.emplace_back(lo.x(), y, z);  // ends
            scene.points.emplace_back(hi.x(), y, z);
        }
    }
}

Scene ground() {
    Scene scene;
    for (float x = -10; x <= 10; x += 0.2f) {
        for (float y = -10; y <= 10; y += 0.2f) scene.points.emplace_back(x, y, 0.0f);
    }
    scene.ground_points = scene.points.size();
    return scene;
}

/// Flags every `every`-th point of [begin, end).
void flag(std::vector<std::uint8_t>& dynamic, std::size_t begin, std::size_t end, int every) {
    for (std::size_t i = begin; i < end; i += every) dynamic[i] = 1;
}

std::size_t count(const std::vector<std::uint8_t>& dynamic, std::size_t begin, std::size_t end) {
    std::size_t n = 0;
    for (std::size_t i = begin; i < end; ++i) n += dynamic[i];
    return n;
}

/// find_scan_objects() the slow way, from the file comment's rules: a point's ground is the
/// lowest point of any ground cell within one cell of its own; the non-ground points' voxels
/// are joined pairwise wherever they touch (all pairs compared); compact components are numbered
/// in order of their first point.
ScanObjects reference_objects(const std::vector<Eigen::Vector3f>& points,
                              const DynamicObjectConfig& config) {
    const auto cell = [](float v, float size) {
        return static_cast<long long>(std::floor(v / size));
    };
    const std::size_t n = points.size();
    ScanObjects result;
    result.object_of.assign(n, ScanObjects::kNoObject);
    std::vector<std::size_t> object_points;  // indices of the non-ground points
    for (std::size_t i = 0; i < n; ++i) {
        float ground = std::numeric_limits<float>::infinity();
        for (const Eigen::Vector3f& q : points) {
            if (std::abs(cell(q.x(), config.ground_cell_m) -
                         cell(points[i].x(), config.ground_cell_m)) <= 1 &&
                std::abs(cell(q.y(), config.ground_cell_m) -
                         cell(points[i].y(), config.ground_cell_m)) <= 1) {
                ground = std::min(ground, q.z());
            }
        }
        if (points[i].z() - ground >= config.min_height_m) object_points.push_back(i);
    }
    const std::size_t m = object_points.size();
    std::vector<std::size_t> root(m);
    std::iota(root.begin(), root.end(), std::size_t{0});
    const auto find = [&](std::size_t a) {
        while (root[a] != a) a = root[a];
        return a;
    };
    for (std::size_t a = 0; a < m; ++a) {
        for (std::size_t b = a + 1; b < m; ++b) {
            const Eigen::Vector3f& p = points[object_points[a]];
            const Eigen::Vector3f& q = points[object_points[b]];
            bool touch = true;
            for (int k = 0; k < 3; ++k) {
                touch =
                    touch && std::abs(cell(p[k], config.voxel_m) - cell(q[k], config.voxel_m)) <= 1;
            }
            if (!touch) continue;
            const std::size_t ra = find(a), rb = find(b);
            if (ra != rb) root[std::max(ra, rb)] = std::min(ra, rb);
        }
    }
    std::vector<std::size_t> size(m, 0);
    std::vector<Eigen::Vector3f> lo(m, Eigen::Vector3f::Constant(1e30f)), hi(m, -lo[0]);
    for (std::size_t a = 0; a < m; ++a) {
        const std::size_t r = find(a);
        ++size[r];
        lo[r] = lo[r].cwiseMin(points[object_points[a]]);
        hi[r] = hi[r].cwiseMax(points[object_points[a]]);
    }
    std::vector<std::uint32_t> id(m, ScanObjects::kNoObject);
    std::vector<bool> seen(m, false);
    for (std::size_t a = 0; a < m; ++a) {
        const std::size_t r = find(a);
        if (!seen[r]) {
            seen[r] = true;
            const Eigen::Vector3f extent = hi[r] - lo[r];
            if (size[r] >= static_cast<std::size_t>(config.min_points) &&
                extent.head<2>().norm() <= config.max_extent_m &&
                extent.z() <= config.max_height_m) {
                id[r] = result.num_objects++;
            }
        }
        result.object_of[object_points[a]] = id[r];
    }
    return result;
}

}  // namespace

TEST(DynamicObjects, ObjectsEqualTheAllPairsReference) {
    // Random clusters of every size over uneven ground: some compact, some too wide or too tall,
    // some too small, some touching diagonally only.
    Pcg32 rng(11);
    DynamicObjectConfig config;
    for (int trial = 0; trial < 4; ++trial) {
        std::vector<Eigen::Vector3f> points;
        for (int i = 0; i < 500; ++i) {
            points.emplace_back(rng.uniform(-15.0f, 15.0f), rng.uniform(-15.0f, 15.0f),
                                rng.uniform(-0.3f, 0.3f));
        }
        for (int c = 0; c < 25; ++c) {
            const Eigen::Vector3f centre(rng.uniform(-14.0f, 14.0f), rng.uniform(-14.0f, 14.0f),
                                         rng.uniform(0.0f, 2.0f));
            const Eigen::Vector3f half(rng.uniform(0.05f, 6.0f), rng.uniform(0.05f, 2.0f),
                                       rng.uniform(0.05f, 3.0f));
            const int count = 1 + static_cast<int>(rng.uniform(0.0f, 60.0f));
            for (int i = 0; i < count; ++i) {
                points.push_back(centre + Eigen::Vector3f(rng.uniform(-1.0f, 1.0f),
                                                          rng.uniform(-1.0f, 1.0f),
                                                          rng.uniform(-1.0f, 1.0f))
                                              .cwiseProduct(half));
            }
        }
        const ScanObjects fast = find_scan_objects(points, config);
        const ScanObjects slow = reference_objects(points, config);
        ASSERT_EQ(fast.num_objects, slow.num_objects) << "trial " << trial;
        ASSERT_GT(slow.num_objects, 3u) << "trial " << trial;
        EXPECT_EQ(fast.object_of, slow.object_of) << "trial " << trial;
    }
}

TEST(DynamicObjects, ACarWithAFewDynamicPointsIsDynamicWholeAndTheGroundUnderItIsNot) {
    Scene scene = ground();
    add_box(scene, {-2.0f, 1.0f, 0.3f}, {2.4f, 2.8f, 1.5f});  // a car body above the road
    const std::size_t car = scene.first_of[0], end = scene.points.size();
    std::vector<std::uint8_t> dynamic(scene.points.size(), 0);
    flag(dynamic, car, end, 5);                  // 20 % of the car seen through
    flag(dynamic, 0, scene.ground_points, 500);  // a few ground points too
    const std::size_t ground_flags = count(dynamic, 0, scene.ground_points);
    const DynamicObjectStats stats = spread_dynamic_to_objects(scene.points, dynamic, {});
    EXPECT_EQ(count(dynamic, car, end), end - car);
    EXPECT_EQ(count(dynamic, 0, scene.ground_points), ground_flags);
    EXPECT_EQ(stats.objects, 1u);
    EXPECT_EQ(stats.objects_dynamic, 1u);
    EXPECT_EQ(stats.points_added, (end - car) - ((end - car + 4) / 5));
}

TEST(DynamicObjects, AWallWiderThanACarKeepsItsPointsOwnVotes) {
    Scene scene = ground();
    add_box(scene, {-9.0f, 5.0f, 0.0f}, {9.0f, 5.3f, 3.0f});  // an 18 m wall
    const std::size_t wall = scene.first_of[0], end = scene.points.size();
    std::vector<std::uint8_t> dynamic(scene.points.size(), 0);
    flag(dynamic, wall, end, 3);  // a third seen through (grazing angles)
    const std::vector<std::uint8_t> before = dynamic;
    const DynamicObjectStats stats = spread_dynamic_to_objects(scene.points, dynamic, {});
    EXPECT_EQ(dynamic, before);
    EXPECT_EQ(stats.objects_dynamic, 0u);
}

TEST(DynamicObjects, TooFewDynamicPointsOrAShareBelowTheThresholdSpreadNothing) {
    Scene scene = ground();
    add_box(scene, {-2.0f, 1.0f, 0.3f}, {2.4f, 2.8f, 1.5f});
    const std::size_t car = scene.first_of[0], end = scene.points.size();
    std::vector<std::uint8_t> dynamic(scene.points.size(), 0);
    flag(dynamic, car, end, 10);  // 10 %: below the 15 % share
    std::vector<std::uint8_t> before = dynamic;
    spread_dynamic_to_objects(scene.points, dynamic, {});
    EXPECT_EQ(dynamic, before);

    // A pedestrian of 12 points with 2 of them dynamic: a share of 17 %, but fewer than 3.
    Scene small = ground();
    const std::size_t person = small.points.size();
    for (int k = 0; k < 12; ++k) small.points.emplace_back(3.0f, 3.0f, 0.3f + 0.12f * k);
    std::vector<std::uint8_t> flags(small.points.size(), 0);
    flags[person] = flags[person + 5] = 1;
    before = flags;
    spread_dynamic_to_objects(small.points, flags, {});
    EXPECT_EQ(flags, before);
    flags[person + 9] = 1;  // a third one: now it spreads
    spread_dynamic_to_objects(small.points, flags, {});
    EXPECT_EQ(count(flags, person, small.points.size()), 12u);
}

TEST(DynamicObjects, SeparateObjectsDoNotShareTheirVotesAndZeroShareIsOff) {
    Scene scene = ground();
    add_box(scene, {-6.0f, 1.0f, 0.3f}, {-2.0f, 2.8f, 1.5f});
    add_box(scene, {-1.0f, 1.0f, 0.3f}, {3.0f, 2.8f, 1.5f});  // 1 m apart
    const std::size_t a = scene.first_of[0], b = scene.first_of[1], end = scene.points.size();
    std::vector<std::uint8_t> dynamic(scene.points.size(), 0);
    flag(dynamic, a, b, 4);
    std::vector<std::uint8_t> off = dynamic;
    DynamicObjectConfig config;
    config.min_dynamic_share = 0.0f;
    const std::vector<std::uint8_t> before = off;
    spread_dynamic_to_objects(scene.points, off, config);
    EXPECT_EQ(off, before);

    spread_dynamic_to_objects(scene.points, dynamic, {});
    EXPECT_EQ(count(dynamic, a, b), b - a);
    EXPECT_EQ(count(dynamic, b, end), 0u);
}

TEST(DynamicObjects, MismatchedFlagsAndBadSettingsAreErrors) {
    const std::vector<Eigen::Vector3f> points = {{0, 0, 0}, {1, 0, 0}};
    std::vector<std::uint8_t> flags(1, 0);
    EXPECT_THROW(spread_dynamic_to_objects(points, flags, {}), DataError);
    flags.assign(2, 0);
    DynamicObjectConfig config;
    config.voxel_m = 0.0f;
    EXPECT_THROW(spread_dynamic_to_objects(points, flags, config), ConfigError);
    config = {};
    config.min_dynamic_share = 1.5f;
    EXPECT_THROW(spread_dynamic_to_objects(points, flags, config), ConfigError);
}
