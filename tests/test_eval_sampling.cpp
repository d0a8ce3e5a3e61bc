// Building blocks of mesh evaluation: surface sampling, voxel downsampling, nearest distances.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/eval/mesh_sampling.hpp"
#include "shine/eval/nearest_distance.hpp"
#include "shine/eval/voxel_downsample.hpp"

namespace shine {
namespace {

constexpr float kFloatTolM = 1e-5f;  // 10 um: float rounding of coordinates of a few metres

/// Two separated right triangles in the z = 0 plane: area 1 m^2 (x in [0, 2]) and 3 m^2
/// (x in [10, 13]).
TriangleMesh two_triangles() {
    TriangleMesh mesh;
    mesh.vertices = {{0, 0, 0}, {2, 0, 0}, {0, 1, 0}, {10, 0, 0}, {13, 0, 0}, {10, 2, 0}};
    mesh.triangles = {{0, 1, 2}, {3, 4, 5}};
    return mesh;
}

std::size_t count_with_x_below(const std::vector<Eigen::Vector3f>& points, float x_m) {
    return std::count_if(points.begin(), points.end(),
                         [x_m](const Eigen::Vector3f& p) { return p.x() < x_m; });
}

TEST(MeshSampling, AreaSumsSkipDegenerateAndUnobservedFaces) {
    TriangleMesh mesh = two_triangles();
    mesh.vertices.push_back({5, 5, 5});
    mesh.triangles.push_back({0, 1, 0});  // repeated vertex: zero area
    mesh.triangles.push_back({0, 1, 6});  // present, to test the observed flag
    EXPECT_NEAR(mesh_surface_area_m2(mesh), 4.0 + 0.5 * 2.0 * std::sqrt(50.0), 1e-9);
    mesh.face_observed = {1, 0, 1, 0};
    EXPECT_NEAR(mesh_surface_area_m2(mesh, FaceSelection::kObserved), 1.0, 1e-9);
}

TEST(MeshSampling, CountsAreProportionalToArea) {
    // Stochastic rounding gives each triangle floor or ceil of area * density, never anything else.
    constexpr double kDensityPerM2 = 1234.5;
    const auto points = sample_mesh_surface(two_triangles(), kDensityPerM2, 7);
    const std::size_t small = count_with_x_below(points, 5.0f);
    const std::size_t large = points.size() - small;
    EXPECT_TRUE(small == 1234 || small == 1235) << small;
    EXPECT_TRUE(large == 3703 || large == 3704) << large;
}

TEST(MeshSampling, TinyTrianglesAreUnbiasedInTotal) {
    // 10,000 triangles of 0.5 m^2 * 0.6 = 0.3 expected points each: without stochastic rounding
    // every triangle would round to 0. The total is a sum of Bernoulli(0.3) draws: mean 3000,
    // standard deviation sqrt(10000 * 0.3 * 0.7) = 46; allow 5 sigma.
    constexpr int kTriangles = 10000;
    constexpr double kDensityPerM2 = 0.6;
    constexpr double kExpected = kTriangles * 0.5 * kDensityPerM2;
    constexpr double kFiveSigma = 5.0 * 45.8;
    TriangleMesh mesh;
    for (int t = 0; t < kTriangles; ++t) {
        const float x = 2.0f * static_cast<float>(t);
        const int base = static_cast<int>(mesh.vertices.size());
        mesh.vertices.insert(mesh.vertices.end(), {{x, 0, 0}, {x + 1, 0, 0}, {x, 1, 0}});
        mesh.triangles.push_back({base, base + 1, base + 2});
    }
    const auto points = sample_mesh_surface(mesh, kDensityPerM2, 3);
    EXPECT_NEAR(static_cast<double>(points.size()), kExpected, kFiveSigma);
}

TEST(MeshSampling, PointsAreUniformInsideTheTriangle) {
    TriangleMesh mesh;
    mesh.vertices = {{1, 1, 1}, {4, 1, 1}, {1, 3, 3}};  // tilted; area 3 * 2 sqrt(2) / 2 = 4.24 m^2
    mesh.triangles = {{0, 1, 2}};
    const auto points = sample_mesh_surface(mesh, 20000.0, 11);
    ASSERT_GT(points.size(), 40000u);
    const Eigen::Vector3d a(1, 1, 1), ab(3, 0, 0), ac(0, 2, 2);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    int in_corner_quarter = 0;  // points with barycentric u > 1/2: a quarter of the area
    for (const auto& p : points) {
        // Solve p = a + u ab + v ac (ab and ac are orthogonal here).
        const Eigen::Vector3d d = p.cast<double>() - a;
        const double u = d.dot(ab) / ab.squaredNorm();
        const double v = d.dot(ac) / ac.squaredNorm();
        ASSERT_GE(u, -1e-6);
        ASSERT_GE(v, -1e-6);
        ASSERT_LE(u + v, 1.0 + 1e-6);
        ASSERT_NEAR((a + u * ab + v * ac - p.cast<double>()).norm(), 0.0, 1e-5);
        mean += p.cast<double>();
        in_corner_quarter += u > 0.5;
    }
    mean /= static_cast<double>(points.size());
    // Uniform points average to the centroid; coordinate std is < 1 m, so the mean's is < 5 mm.
    constexpr double kMeanTolM = 0.02;
    EXPECT_NEAR((mean - Eigen::Vector3d(2, 5.0 / 3, 5.0 / 3)).norm(), 0.0, kMeanTolM);
    // Binomial(n, 1/4): std of the share is < 0.0025 for n > 40000.
    constexpr double kShareTol = 0.0125;
    EXPECT_NEAR(in_corner_quarter / static_cast<double>(points.size()), 0.25, kShareTol);
}

TEST(MeshSampling, SameSeedSamePointsOtherSeedOtherPoints) {
    const TriangleMesh mesh = two_triangles();
    const auto first = sample_mesh_surface(mesh, 500.0, 42);
    const auto again = sample_mesh_surface(mesh, 500.0, 42);
    const auto other = sample_mesh_surface(mesh, 500.0, 43);
    ASSERT_EQ(first.size(), again.size());
    for (std::size_t i = 0; i < first.size(); ++i) EXPECT_EQ(first[i], again[i]) << i;
    ASSERT_FALSE(other.empty());
    EXPECT_NE(first.front(), other.front());
}

TEST(MeshSampling, ObservedSamplesAreTheObservedSubsetOfAllSamples) {
    TriangleMesh mesh = two_triangles();
    mesh.face_observed = {0, 1};
    const auto all = sample_mesh_surface(mesh, 300.0, 5, FaceSelection::kAll);
    const auto observed = sample_mesh_surface(mesh, 300.0, 5, FaceSelection::kObserved);
    EXPECT_EQ(count_with_x_below(observed, 5.0f), 0u);
    const std::vector<Eigen::Vector3f> all_large(all.begin() + count_with_x_below(all, 5.0f),
                                                 all.end());
    EXPECT_EQ(observed, all_large);
}

TEST(MeshSampling, DegenerateTrianglesGetNoPoints) {
    TriangleMesh mesh;
    mesh.vertices = {{0, 0, 0}, {1, 1, 1}, {2, 2, 2}, {0, 0, 0}};
    mesh.triangles = {{0, 1, 2}, {0, 3, 1}};  // collinear; repeated position
    EXPECT_TRUE(sample_mesh_surface(mesh, 1e6, 1).empty());
}

TEST(MeshSampling, RejectsMalformedInput) {
    TriangleMesh mesh = two_triangles();
    EXPECT_THROW(sample_mesh_surface(mesh, 0.0, 1), DataError);
    EXPECT_THROW(sample_mesh_surface(mesh, std::numeric_limits<double>::quiet_NaN(), 1), DataError);
    mesh.face_observed = {1};  // one flag for two triangles
    EXPECT_THROW(sample_mesh_surface(mesh, 10.0, 1), DataError);
    mesh.face_observed.clear();
    mesh.triangles.push_back({0, 1, 6});  // vertex 6 does not exist
    EXPECT_THROW(sample_mesh_surface(mesh, 10.0, 1), DataError);
    EXPECT_THROW(mesh_surface_area_m2(mesh), DataError);
}

TEST(VoxelDownsample, OneCentroidPerVoxelWithFloorIndexing) {
    constexpr double kVoxelM = 0.1;
    const std::vector<Eigen::Vector3f> points = {
        {0.01f, 0.01f, 0.01f},  {0.03f, 0.05f, 0.07f},  // voxel (0, 0, 0)
        {-0.01f, 0.01f, 0.01f},                         // voxel (-1, 0, 0): floor, not truncate
        {0.25f, 0.01f, 0.01f},  {0.27f, 0.03f, 0.05f}, {0.29f, 0.05f, 0.03f}};  // voxel (2, 0, 0)
    const auto centroids = voxel_downsample_centroids(points, kVoxelM);
    ASSERT_EQ(centroids.size(), 3u);  // ordered by voxel index
    EXPECT_LT((centroids[0] - Eigen::Vector3f(-0.01f, 0.01f, 0.01f)).norm(), kFloatTolM);
    EXPECT_LT((centroids[1] - Eigen::Vector3f(0.02f, 0.03f, 0.04f)).norm(), kFloatTolM);
    EXPECT_LT((centroids[2] - Eigen::Vector3f(0.27f, 0.03f, 0.03f)).norm(), kFloatTolM);
}

TEST(VoxelDownsample, OutputDoesNotDependOnInputOrder) {
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> coordinate(-1.0f, 1.0f);
    std::vector<Eigen::Vector3f> points(20000);
    for (auto& p : points) p = {coordinate(rng), coordinate(rng), coordinate(rng)};
    const auto reference = voxel_downsample_centroids(points, 0.2);
    std::shuffle(points.begin(), points.end(), rng);
    EXPECT_EQ(voxel_downsample_centroids(points, 0.2), reference);
    EXPECT_EQ(reference.size(), 1000u);  // 10^3 voxels of 0.2 m in [-1, 1)^3, all occupied
}

TEST(VoxelDownsample, RejectsBadInput) {
    EXPECT_THROW(voxel_downsample_centroids({{0, 0, 0}}, 0.0), DataError);
    EXPECT_THROW(voxel_downsample_centroids({{std::nanf(""), 0, 0}}, 0.02), DataError);
    EXPECT_THROW(voxel_downsample_centroids({{1e30f, 0, 0}}, 0.02), DataError);
    EXPECT_TRUE(voxel_downsample_centroids({}, 0.02).empty());
}

TEST(NearestDistance, MatchesBruteForceAndRespectsTheCap) {
    std::mt19937 rng(4);
    std::uniform_real_distribution<float> coordinate(0.0f, 2.0f);
    std::vector<Eigen::Vector3f> targets(3000), queries(2000);
    for (auto& p : targets) p = {coordinate(rng), coordinate(rng), coordinate(rng)};
    for (auto& p : queries) p = {coordinate(rng), coordinate(rng), 3.0f * coordinate(rng)};
    constexpr double kCapM = 0.15;
    const auto capped = nearest_distances_m(targets, queries, kCapM);
    const auto uncapped =
        nearest_distances_m(targets, queries, std::numeric_limits<double>::infinity());
    ASSERT_EQ(capped.size(), queries.size());
    int beyond_cap = 0;
    for (std::size_t i = 0; i < queries.size(); ++i) {
        float brute_m = std::numeric_limits<float>::infinity();
        for (const auto& t : targets) brute_m = std::min(brute_m, (t - queries[i]).norm());
        EXPECT_NEAR(uncapped[i], brute_m, kFloatTolM) << i;
        EXPECT_NEAR(capped[i], std::min(brute_m, static_cast<float>(kCapM)), kFloatTolM) << i;
        beyond_cap += brute_m > kCapM;
    }
    EXPECT_GT(beyond_cap, 100);  // the cap is exercised (queries reach z = 6 m above the targets)
}

TEST(NearestDistance, EmptyTargetsGiveTheCap) {
    const auto d = nearest_distances_m({}, {{0, 0, 0}, {1, 1, 1}}, 2.0);
    EXPECT_EQ(d, std::vector<float>(2, 2.0f));
    EXPECT_TRUE(nearest_distances_m({{0, 0, 0}}, {}, 2.0).empty());
    EXPECT_THROW(nearest_distances_m({{0, 0, 0}}, {{0, 0, 0}}, 0.0), DataError);
}

}  // namespace
}  // namespace shine
