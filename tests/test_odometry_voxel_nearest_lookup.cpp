// VoxelNearestLookup: the point nearest to each voxel's centre, against a brute force, on random
// points, on a grid full of equal distances and far from the world origin; what it holds and
// refuses. A walk that only hands each voxel's nearest point on to its neighbours (vector
// propagation) fails the first test: 3756 voxel centres missed or a few millimetres off.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "shine/core/error.hpp"
#include "shine/odometry/voxel_nearest_lookup.hpp"

using namespace shine;

namespace {

/// The smallest distance from `q` to any of `points`.
double brute_nearest_m(const std::vector<Eigen::Vector3d>& points, const Eigen::Vector3d& q) {
    double best = std::numeric_limits<double>::infinity();
    for (const Eigen::Vector3d& p : points) best = std::min(best, (p - q).norm());
    return best;
}

/// Checks every voxel centre of a box around the points: held exactly when a point is within
/// the radius of it, and then with a point at the brute force's distance. Returns the centres
/// held.
int check_against_brute_force(const std::vector<Eigen::Vector3d>& points, double voxel_m,
                              double radius_m, const Eigen::Vector3d& lo,
                              const Eigen::Vector3d& hi) {
    const VoxelNearestLookup lookup(points, voxel_m, radius_m);
    const Eigen::Vector3d origin = points.front();
    const Eigen::Vector3i first = ((lo - origin) / voxel_m).array().floor().cast<int>();
    const Eigen::Vector3i last = ((hi - origin) / voxel_m).array().floor().cast<int>();
    int held = 0;
    for (int x = first.x(); x <= last.x(); ++x) {
        for (int y = first.y(); y <= last.y(); ++y) {
            for (int z = first.z(); z <= last.z(); ++z) {
                const Eigen::Vector3d centre =
                    origin + (Eigen::Vector3d(x, y, z).array() + 0.5).matrix() * voxel_m;
                const double expected_m = brute_nearest_m(points, centre);
                // Any query inside the voxel gets the centre's answer.
                const Eigen::Vector3d query = centre + Eigen::Vector3d(0.3, -0.2, 0.45) * voxel_m;
                const long j = lookup.find(query);
                // The tree's coordinates are float, relative to the first point: distances within
                // 10 micrometres of the radius may go either way.
                if (expected_m > radius_m + 1e-5) {
                    EXPECT_EQ(j, -1) << "centre " << centre.transpose();
                    continue;
                }
                if (expected_m < radius_m - 1e-5) {
                    EXPECT_GE(j, 0) << "centre " << centre.transpose();
                }
                if (j < 0) continue;
                ++held;
                EXPECT_NEAR((points[j] - centre).norm(), expected_m, 1e-5)
                    << "centre " << centre.transpose();
            }
        }
    }
    return held;
}

}  // namespace

TEST(VoxelNearestLookup, EachVoxelHoldsThePointNearestToItsCentre) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<Eigen::Vector3d> points;
    // Three noisy planes and a scatter, as a surface's vertices are, and a far-off point.
    for (int i = 0; i < 1500; ++i) {
        const double a = 6.0 * u(rng), b = 4.0 * u(rng), n = 0.02 * (u(rng) - 0.5);
        points.emplace_back(a, b, n);
        points.emplace_back(a, n, 0.5 * b);
        points.emplace_back(n + 3.0, a - 1.0, b - 2.0);
    }
    for (int i = 0; i < 200; ++i) points.emplace_back(6 * u(rng), 4 * u(rng), 3 * u(rng) - 2);
    points.emplace_back(30.0, 30.0, 30.0);
    const int held =
        check_against_brute_force(points, 0.25, 1.0, {-1.5, -1.5, -3.5}, {7.5, 5.5, 2.5});
    EXPECT_GT(held, 10000);
    // A coarse lookup over the same points, with a wide radius.
    EXPECT_GT(check_against_brute_force(points, 1.0, 4.0, {-5, -5, -7}, {11, 9, 7}), 1000);
}

TEST(VoxelNearestLookup, EqualDistancesOnAGridFarFromTheOrigin) {
    // Points on an exact grid half a voxel off the voxels' corners: many centres are equally far
    // from several points; the distance must still be the smallest. Far from the world origin
    // (UTM-like coordinates), the voxels are placed relative to the first point.
    const Eigen::Vector3d far(500000.0, 4000000.0, 100.0);
    std::vector<Eigen::Vector3d> points;
    for (int x = 0; x < 12; ++x) {
        for (int y = 0; y < 8; ++y) points.push_back(far + Eigen::Vector3d(0.5 * x, 0.5 * y, 0.0));
    }
    EXPECT_GT(check_against_brute_force(points, 0.25, 0.8, far + Eigen::Vector3d(-1, -1, -1),
                                        far + Eigen::Vector3d(6.5, 4.5, 1)),
              1000);
}

TEST(VoxelNearestLookup, NothingHeldAndBadSettingsRefused) {
    const VoxelNearestLookup empty({}, 0.25, 1.0);
    EXPECT_EQ(empty.voxels(), 0u);
    EXPECT_EQ(empty.find(Eigen::Vector3d::Zero()), -1);
    const VoxelNearestLookup one({Eigen::Vector3d(1, 2, 3)}, 0.5, 0.45);
    EXPECT_EQ(one.find(Eigen::Vector3d(1, 2, 3)), 0);
    EXPECT_EQ(one.find(Eigen::Vector3d(5, 2, 3)), -1);
    EXPECT_EQ(one.find(Eigen::Vector3d(std::nan(""), 2, 3)), -1);
    EXPECT_THROW(VoxelNearestLookup({Eigen::Vector3d::Zero()}, 0.0, 1.0), ConfigError);
    EXPECT_THROW(VoxelNearestLookup({Eigen::Vector3d::Zero()}, 0.1, -1.0), ConfigError);
    EXPECT_THROW(VoxelNearestLookup({Eigen::Vector3d::Zero()}, 0.5, 0.4), ConfigError);
    EXPECT_THROW(VoxelNearestLookup({Eigen::Vector3d::Zero()}, 0.001, 2.0), ConfigError);
}
