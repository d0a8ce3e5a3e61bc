// Rays grouped by voxel (preprocess.voxel_points: all): the grouped preprocessing against the
// thinning it generalises, the filter that keeps the groups, RaySet's groups, the mixture draw of
// RayDrawer, and the normals shared within a group.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/geometry/voxel_groups.hpp"
#include "shine/io/preprocess.hpp"
#include "shine/sampling/ray_draw.hpp"
#include "shine/sampling/ray_set.hpp"
#include "shine/sampling/surface_normals.hpp"

using namespace shine;

namespace {

PreprocessConfig voxels_of(double size_m, VoxelPoints keep) {
    PreprocessConfig c;
    c.min_range_m = 0.0;
    c.max_range_m = std::numeric_limits<double>::infinity();
    c.voxel_downsample_m = size_m;
    c.voxel_points = keep;
    return c;
}

std::vector<Eigen::Vector3f> random_points(int n, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-5.0f, 5.0f);
    std::vector<Eigen::Vector3f> points;
    for (int i = 0; i < n; ++i) points.emplace_back(u(rng), u(rng), 0.2f * u(rng));
    return points;
}

}  // namespace

TEST(VoxelGroups, GroupedPreprocessKeepsEveryPointAndLeadsEachVoxelWithTheThinnedPoint) {
    const std::vector<Eigen::Vector3f> points = random_points(5000, 3);
    const auto thinned =
        preprocess_scan(points, voxels_of(1.0, VoxelPoints::kNearest), "s", nullptr);
    PreprocessStats stats;
    std::vector<std::uint32_t> begin;
    const auto grouped =
        preprocess_scan(points, voxels_of(1.0, VoxelPoints::kAll), "s", &stats, &begin);
    ASSERT_EQ(grouped.size(), points.size());
    EXPECT_EQ(stats.dropped_downsample, 0u);
    EXPECT_EQ(stats.output, points.size());
    ASSERT_EQ(begin.size(), thinned.size());
    ASSERT_EQ(begin.front(), 0u);
    for (std::size_t g = 0; g < begin.size(); ++g) {
        // The run's first point is the one thinning keeps, and the whole run shares its voxel.
        EXPECT_EQ(grouped[begin[g]], thinned[g]) << "voxel " << g;
        const std::size_t end = g + 1 < begin.size() ? begin[g + 1] : grouped.size();
        ASSERT_LT(begin[g], end);
        const Eigen::Vector3f voxel = thinned[g].array().floor();
        for (std::size_t i = begin[g]; i < end; ++i) {
            EXPECT_EQ(Eigen::Vector3f(grouped[i].array().floor()), voxel) << "point " << i;
        }
    }
    // Without the caller's list, or with `nearest`, the result is the thinned scan.
    EXPECT_TRUE(preprocess_scan(points, voxels_of(1.0, VoxelPoints::kAll), "s") == thinned);
    std::vector<std::uint32_t> none = {7};
    EXPECT_TRUE(preprocess_scan(points, voxels_of(1.0, VoxelPoints::kNearest), "s", nullptr,
                                &none) == thinned);
    EXPECT_TRUE(none.empty());
    // And the grouped order does not depend on the input order.
    std::vector<Eigen::Vector3f> shuffled = points;
    std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(5));
    std::vector<std::uint32_t> begin2;
    EXPECT_TRUE(preprocess_scan(shuffled, voxels_of(1.0, VoxelPoints::kAll), "s", nullptr,
                                &begin2) == grouped);
    EXPECT_EQ(begin2, begin);
}

TEST(VoxelGroups, FilterKeepsRunsAndDropsEmptiedOnes) {
    // Runs {0,1,2}, {3,4}, {5}, {6,7}.
    std::vector<Eigen::Vector3f> points;
    for (int i = 0; i < 8; ++i) points.emplace_back(float(i), 0.0f, 0.0f);
    std::vector<std::uint32_t> begin = {0, 3, 5, 6};
    // Drop the first run's leader, the whole second run and the last point.
    const std::vector<bool> keep = {false, true, true, false, false, true, true, false};
    std::vector<std::size_t> runs;  // the run each point is reported in
    EXPECT_EQ(filter_voxel_grouped(points, begin,
                                   [&](std::size_t i, std::size_t run) {
                                       runs.push_back(run);
                                       return bool(keep[i]);
                                   }),
              4u);
    ASSERT_EQ(points.size(), 4u);
    EXPECT_EQ(points[0].x(), 1.0f);
    EXPECT_EQ(points[1].x(), 2.0f);
    EXPECT_EQ(points[2].x(), 5.0f);
    EXPECT_EQ(points[3].x(), 6.0f);
    EXPECT_EQ(begin, (std::vector<std::uint32_t>{0, 2, 3}));
    EXPECT_EQ(runs, (std::vector<std::size_t>{0, 0, 0, 1, 1, 2, 3, 3}));
    // Ungrouped points stay ungrouped.
    std::vector<std::uint32_t> ungrouped;
    EXPECT_EQ(filter_voxel_grouped(points, ungrouped,
                                   [](std::size_t i, std::size_t run) {
                                       EXPECT_EQ(run, i);  // ungrouped: each point its own run
                                       return i != 1;
                                   }),
              1u);
    EXPECT_EQ(points.size(), 3u);
    EXPECT_TRUE(
        ungrouped.empty());  // Values per point (a ray origin each, say) follow their points.
    std::vector<Eigen::Vector3f> values;
    for (const Eigen::Vector3f& p : points) values.push_back(10.0f * p);
    EXPECT_EQ(filter_voxel_grouped(
                  points, ungrouped, [](std::size_t i, std::size_t) { return i != 0; }, &values),
              1u);
    ASSERT_EQ(values.size(), points.size());
    for (std::size_t i = 0; i < points.size(); ++i) EXPECT_EQ(values[i], 10.0f * points[i]);
}

TEST(VoxelGroups, RaySetKeepsGroupsPerScanAndRejectsBadStarts) {
    RaySet rays;
    const Eigen::Vector3f o = Eigen::Vector3f::Zero();
    const std::vector<Eigen::Vector3f> three(3, Eigen::Vector3f(1.0f, 0.0f, 0.0f));
    const std::vector<Eigen::Vector3f> five(5, Eigen::Vector3f(2.0f, 0.0f, 0.0f));
    rays.add_scan(o, three);  // ungrouped: three groups of one
    EXPECT_FALSE(rays.grouped());
    EXPECT_EQ(rays.num_groups(), 3u);
    EXPECT_EQ(rays.group_at_or_after(2), 2u);
    rays.add_scan(o, five, {0, 2});  // groups {3,4}, {5,6,7}
    rays.add_scan(o, {});
    rays.add_scan(o, three);  // ungrouped after grouped: one group per ray
    ASSERT_TRUE(rays.grouped());
    EXPECT_EQ(rays.num_groups(), 3u + 2u + 3u);
    EXPECT_EQ(rays.first_ray_of_group(3), 3u);
    EXPECT_EQ(rays.first_ray_of_group(4), 5u);
    EXPECT_EQ(rays.first_ray_of_group(5), 8u);
    EXPECT_EQ(rays.first_ray_of_group(rays.num_groups()), rays.num_rays());
    EXPECT_EQ(rays.group_at_or_after(rays.first_ray(1)), 3u);
    EXPECT_EQ(rays.group_at_or_after(rays.first_ray(2)), 5u);
    EXPECT_EQ(rays.group_at_or_after(rays.num_rays()), rays.num_groups());
    EXPECT_EQ(rays.scan_voxel_begin(1), (std::vector<std::uint32_t>{0, 2}));
    EXPECT_TRUE(rays.scan_voxel_begin(2).empty());
    EXPECT_EQ(rays.scan_voxel_begin(3), (std::vector<std::uint32_t>{0, 1, 2}));
    EXPECT_THROW(rays.add_scan(o, five, {1, 2}), DataError);  // does not start at 0
    EXPECT_THROW(rays.add_scan(o, five, {0, 2, 2}), DataError);
    EXPECT_THROW(rays.add_scan(o, five, {0, 5}), DataError);  // past the end
}

TEST(VoxelGroups, DrawerMixesVoxelsAndPointsInTheConfiguredShares) {
    // Scan 0 (ungrouped, 4 rays) is outside the range; scan 1: one voxel of 1 ray and one of 99.
    RaySet rays;
    rays.add_scan(Eigen::Vector3f::Zero(), std::vector<Eigen::Vector3f>(4));
    rays.add_scan(Eigen::Vector3f::Zero(), std::vector<Eigen::Vector3f>(100), {0, 1});
    const std::size_t lone = rays.first_ray(1);
    const int n = 200000;
    for (const float share : {0.0f, 0.5f, 1.0f}) {
        const RayDrawer drawer(rays, rays.first_ray(1), rays.num_rays(), share);
        Pcg32 rng(11);
        int lone_draws = 0;
        for (int i = 0; i < n; ++i) {
            const std::size_t ray = drawer.draw(rng);
            ASSERT_GE(ray, lone);
            ASSERT_LT(ray, rays.num_rays());
            lone_draws += ray == lone;
        }
        // P(lone) = (1 - share) / 2 voxels + share / 100 points.
        const double expected = (1.0 - share) / 2.0 + share / 100.0;
        const double sigma = std::sqrt(expected * (1.0 - expected) / n);
        EXPECT_NEAR(lone_draws / double(n), expected, 5.0 * sigma + 1e-9) << "share " << share;
    }
    // Ungrouped rays: exactly one plain uniform draw per ray, whatever the share.
    RaySet plain;
    plain.add_scan(Eigen::Vector3f::Zero(), std::vector<Eigen::Vector3f>(37));
    const RayDrawer drawer(plain, 5, 37, 0.5f);
    Pcg32 a(3), b(3);
    for (int i = 0; i < 1000; ++i) ASSERT_EQ(drawer.draw(a), 5 + b.below64(32));
}

TEST(VoxelGroups, NormalsAreTheThinnedScansAndSharedWithinAVoxel) {
    // A tilted plane sampled densely: the grouped rays' leaders are the thinned points.
    std::vector<Eigen::Vector3f> points;
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> u(-4.0f, 4.0f);
    for (int i = 0; i < 20000; ++i) {
        const float x = u(rng), y = u(rng);
        points.emplace_back(x, y, -2.0f + 0.1f * x + 0.05f * y);
    }
    std::vector<std::uint32_t> begin;
    const auto grouped =
        preprocess_scan(points, voxels_of(0.25, VoxelPoints::kAll), "s", nullptr, &begin);
    const auto thinned = preprocess_scan(points, voxels_of(0.25, VoxelPoints::kNearest), "s");
    RaySet all_rays, thin_rays;
    all_rays.add_scan(Eigen::Vector3f::Zero(), grouped, begin);
    thin_rays.add_scan(Eigen::Vector3f::Zero(), thinned);
    NormalConfig config;
    const auto all_normals = estimate_ray_normals(all_rays, config);
    const auto thin_normals = estimate_ray_normals(thin_rays, config);
    std::size_t with_normal = 0;
    for (std::size_t g = 0; g < begin.size(); ++g) {
        const std::size_t end = g + 1 < begin.size() ? begin[g + 1] : grouped.size();
        ASSERT_EQ(all_normals[begin[g]], thin_normals[g]) << "voxel " << g;
        with_normal += thin_normals[g].norm() > 0.5f;
        for (std::size_t r = begin[g] + 1; r < end; ++r) {
            ASSERT_EQ(all_normals[r], all_normals[begin[g]]) << "ray " << r;
        }
    }
    EXPECT_GT(with_normal, begin.size() * 9 / 10);
}
