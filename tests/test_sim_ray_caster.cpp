// The ray caster (geometry module) on the simulator's meshes, against brute force.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "shine/core/error.hpp"
#include "shine/geometry/ray_caster.hpp"
#include "shine/sim/mesh_primitives.hpp"

namespace {

using shine::RayCaster;
using shine::RayHit;
using shine::TriangleMesh;

constexpr double kDistanceToleranceM = 1e-5;  // 10 um

/// The plane z = 0 over [-200, 200]^2 as two float-exact triangles, normal +z.
TriangleMesh make_ground_plane() {
    TriangleMesh mesh;
    mesh.vertices = {{-200, -200, 0}, {200, -200, 0}, {200, 200, 0}, {-200, 200, 0}};
    mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
    return mesh;
}

Eigen::Vector3d random_unit(std::mt19937_64& rng) {
    std::normal_distribution<double> normal;
    Eigen::Vector3d d(normal(rng), normal(rng), normal(rng));
    return d.normalized();
}

/// Entry distance of a ray into an axis-aligned box (slab method), or -1 if it misses.
double analytic_box_entry(const Eigen::Vector3d& o, const Eigen::Vector3d& d,
                          const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
    double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
    for (int a = 0; a < 3; ++a) {
        const double ta = (lo[a] - o[a]) / d[a];
        const double tb = (hi[a] - o[a]) / d[a];
        t0 = std::max(t0, std::min(ta, tb));
        t1 = std::min(t1, std::max(ta, tb));
    }
    return t0 <= t1 ? t0 : -1.0;
}

TEST(MollerTrumbore, HitsInsideMissesOutsideAndParallel) {
    const Eigen::Vector3d v0(0, 0, 0), v1(1, 0, 0), v2(0, 1, 0);
    double t = -1.0;
    EXPECT_TRUE(
        shine::intersect_ray_triangle({0.25, 0.25, 2.0}, {0, 0, -1}, v0, v1, v2, 0.0, 10.0, t));
    EXPECT_DOUBLE_EQ(t, 2.0);
    // Two-sided: the same triangle seen from below.
    EXPECT_TRUE(
        shine::intersect_ray_triangle({0.25, 0.25, -3.0}, {0, 0, 1}, v0, v1, v2, 0.0, 10.0, t));
    EXPECT_DOUBLE_EQ(t, 3.0);
    EXPECT_FALSE(
        shine::intersect_ray_triangle({0.75, 0.75, 2.0}, {0, 0, -1}, v0, v1, v2, 0.0, 10.0, t));
    EXPECT_FALSE(
        shine::intersect_ray_triangle({0.25, 0.25, 0.0}, {1, 0, 0}, v0, v1, v2, 0.0, 10.0, t));
    // Outside [t_min, t_max].
    EXPECT_FALSE(
        shine::intersect_ray_triangle({0.25, 0.25, 2.0}, {0, 0, -1}, v0, v1, v2, 0.0, 1.5, t));
    EXPECT_FALSE(
        shine::intersect_ray_triangle({0.25, 0.25, 2.0}, {0, 0, -1}, v0, v1, v2, 2.5, 10.0, t));
}

TEST(RayCaster, PlaneDistancesAreExact) {
    const RayCaster caster(make_ground_plane());
    std::mt19937_64 rng(11);
    std::uniform_real_distribution<double> xy(-20.0, 20.0), height(0.3, 5.0);
    int hits = 0;
    for (int i = 0; i < 2000; ++i) {
        const Eigen::Vector3d origin(xy(rng), xy(rng), height(rng));
        Eigen::Vector3d direction = random_unit(rng);
        if (direction.z() > -0.05) direction.z() = -0.05 - std::abs(direction.z());
        direction.normalize();
        const double expected = origin.z() / -direction.z();
        const RayHit hit = caster.cast(origin, direction);
        if (expected > 250.0) continue;  // may leave the finite plane
        ASSERT_TRUE(hit.hit()) << "ray " << i;
        EXPECT_NEAR(hit.distance_m, expected, kDistanceToleranceM) << "ray " << i;
        ++hits;
        // Upward rays miss.
        EXPECT_FALSE(caster.cast(origin, -direction).hit());
    }
    EXPECT_GT(hits, 1500);
}

TEST(RayCaster, RefinedBoxDistancesAreExact) {
    const Eigen::Vector3f lo(-1.0f, -0.5f, 0.0f), hi(2.0f, 1.5f, 3.0f);
    TriangleMesh box = shine::sim::make_box_mesh(lo, hi);
    shine::sim::refine_to_max_edge(box, 0.3f);
    ASSERT_GT(box.triangles.size(), 500u);
    const RayCaster caster(box);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> inside(0.05, 0.95);
    for (int i = 0; i < 2000; ++i) {
        // From a point 3..10 m away towards a random point inside the box.
        const Eigen::Vector3d target(lo.x() + inside(rng) * (hi.x() - lo.x()),
                                     lo.y() + inside(rng) * (hi.y() - lo.y()),
                                     lo.z() + inside(rng) * (hi.z() - lo.z()));
        const Eigen::Vector3d origin =
            target + random_unit(rng) * std::uniform_real_distribution<double>(5.0, 10.0)(rng);
        const Eigen::Vector3d direction = (target - origin).normalized();
        const double expected =
            analytic_box_entry(origin, direction, lo.cast<double>(), hi.cast<double>());
        ASSERT_GT(expected, 0.0);
        const RayHit hit = caster.cast(origin, direction);
        ASSERT_TRUE(hit.hit()) << "ray " << i;
        EXPECT_NEAR(hit.distance_m, expected, kDistanceToleranceM) << "ray " << i;
    }
    // From inside, the closest hit is the exit through the wall.
    const RayHit from_inside = caster.cast({0.0, 0.0, 1.0}, {1.0, 0.0, 0.0});
    ASSERT_TRUE(from_inside.hit());
    EXPECT_NEAR(from_inside.distance_m, 2.0, kDistanceToleranceM);
}

/// Boxes and ellipsoids scattered over [-10, 10]^3, refined to edges of at most `max_edge_m`.
TriangleMesh make_random_scene(std::mt19937_64& rng, float max_edge_m) {
    TriangleMesh scene;
    std::uniform_real_distribution<float> position(-10.0f, 10.0f), size(0.3f, 3.0f);
    for (int i = 0; i < 12; ++i) {
        const Eigen::Vector3f corner(position(rng), position(rng), position(rng));
        shine::sim::append_mesh(
            scene, shine::sim::make_box_mesh(
                       corner, corner + Eigen::Vector3f(size(rng), size(rng), size(rng))));
        TriangleMesh ellipsoid =
            shine::sim::make_ellipsoid_mesh(Eigen::Vector3f(size(rng), size(rng), size(rng)), 2);
        const Eigen::Vector3f center(position(rng), position(rng), position(rng));
        for (auto& v : ellipsoid.vertices) v += center;
        shine::sim::append_mesh(scene, ellipsoid);
    }
    shine::sim::refine_to_max_edge(scene, max_edge_m);
    return scene;
}

TEST(RayCaster, BvhEqualsBruteForceOnRandomRays) {
    std::mt19937_64 rng(3);
    const TriangleMesh scene = make_random_scene(rng, 0.5f);
    std::uniform_real_distribution<float> position(-10.0f, 10.0f);
    ASSERT_GT(scene.triangles.size(), 5000u);
    const RayCaster caster(scene);
    int hits = 0;
    for (int i = 0; i < 3000; ++i) {
        const Eigen::Vector3d origin(1.5 * position(rng), 1.5 * position(rng), 1.5 * position(rng));
        // Half the rays aim at a vertex (many hits, many grazing edges), half go anywhere.
        const Eigen::Vector3d direction =
            i % 2 == 0 ? (scene.vertices[rng() % scene.vertices.size()].cast<double>() - origin)
                             .normalized()
                       : random_unit(rng);
        const double t_max = i % 3 == 0 ? 8.0 : std::numeric_limits<double>::infinity();
        const double t_min = i % 5 == 0 ? 2.0 : 0.0;
        const RayHit fast = caster.cast(origin, direction, t_min, t_max);
        const RayHit slow = caster.cast_brute_force(origin, direction, t_min, t_max);
        ASSERT_EQ(fast.triangle_id, slow.triangle_id) << "ray " << i;
        if (slow.hit()) {
            ++hits;
            EXPECT_EQ(fast.distance_m, slow.distance_m) << "ray " << i;
            EXPECT_GE(fast.distance_m, t_min);
            EXPECT_LE(fast.distance_m, t_max);
        } else {
            EXPECT_TRUE(std::isinf(fast.distance_m));
        }
    }
    EXPECT_GT(hits, 1000);
    EXPECT_LT(hits, 2900);
}

TEST(RayCaster, ParallelBuildGivesTheSerialTreeAndHits) {
    std::mt19937_64 rng(7);
    const TriangleMesh scene = make_random_scene(rng, 0.3f);
    ASSERT_GT(scene.triangles.size(), 20000u);
    const std::size_t n = scene.triangles.size();
    shine::BvhBuildOptions serial_options;
    serial_options.parallel_min_triangles = std::numeric_limits<std::size_t>::max();
    const RayCaster serial(scene, 0, n, serial_options);
    // Down to single triangles as tasks, a few levels as tasks, and the default.
    for (const std::size_t min_triangles : {std::size_t{0}, std::size_t{64}, std::size_t{4096},
                                            shine::BvhBuildOptions{}.parallel_min_triangles}) {
        shine::BvhBuildOptions options;
        options.parallel_min_triangles = min_triangles;
        const RayCaster parallel(scene, 0, n, options);
        EXPECT_EQ(parallel.num_nodes(), serial.num_nodes()) << min_triangles;
        EXPECT_TRUE(parallel.same_bvh(serial)) << min_triangles;
    }
    // A block of the mesh: triangle ids count in the whole mesh either way.
    shine::BvhBuildOptions options;
    options.parallel_min_triangles = 256;
    const RayCaster block_parallel(scene, 1000, n / 2, options);
    const RayCaster block_serial(scene, 1000, n / 2, serial_options);
    EXPECT_TRUE(block_parallel.same_bvh(block_serial));
    EXPECT_FALSE(block_parallel.same_bvh(serial));

    const RayCaster parallel(scene, 0, n, options);
    std::uniform_real_distribution<double> position(-15.0, 15.0);
    int hits = 0;
    for (int i = 0; i < 3000; ++i) {
        const Eigen::Vector3d origin(position(rng), position(rng), position(rng));
        const Eigen::Vector3d direction =
            i % 2 == 0 ? (scene.vertices[rng() % scene.vertices.size()].cast<double>() - origin)
                             .normalized()
                       : random_unit(rng);
        const double t_min = i % 5 == 0 ? 2.0 : 0.0;
        const RayHit a = parallel.cast(origin, direction, t_min);
        const RayHit b = serial.cast(origin, direction, t_min);
        const RayHit c = serial.cast_brute_force(origin, direction, t_min);
        ASSERT_EQ(a.triangle_id, b.triangle_id) << "ray " << i;
        ASSERT_EQ(a.triangle_id, c.triangle_id) << "ray " << i;
        EXPECT_EQ(a.distance_m, b.distance_m) << "ray " << i;
        EXPECT_EQ(a.distance_m, c.distance_m) << "ray " << i;
        const RayHit d = block_parallel.cast(origin, direction, t_min);
        const RayHit e = block_serial.cast(origin, direction, t_min);
        ASSERT_EQ(d.triangle_id, e.triangle_id) << "ray " << i;
        EXPECT_EQ(d.distance_m, e.distance_m) << "ray " << i;
        hits += a.hit();
    }
    EXPECT_GT(hits, 1000);
}

TEST(RayCaster, EmptyMeshNeverHitsAndBadIndexThrows) {
    const RayCaster empty{TriangleMesh{}};
    EXPECT_FALSE(empty.cast({0, 0, 0}, {1, 0, 0}).hit());
    TriangleMesh bad = make_ground_plane();
    bad.triangles.push_back({0, 1, 7});
    EXPECT_THROW(RayCaster{bad}, shine::ConfigError);
}

}  // namespace
