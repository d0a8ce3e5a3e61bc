// The ghost measure on hand-made meshes: the static reference plus a quad inside a mover's swept
// box counts that quad's area; a quad off the static scene but away from every mover does not.
#include <gtest/gtest.h>

#include "mesh_test_support.hpp"
#include "shine/eval/ghost_area.hpp"

namespace shine {
namespace {

constexpr double kAreaRelTol = 0.03;  // 3 %: sampling at 1 point per cm^2

using mesh_test::add_quad;

/// The static reference: a 10 m x 10 m floor at z = 0, all observed.
TriangleMesh floor_mesh() {
    TriangleMesh mesh;
    add_quad(mesh, {0, -5, 0}, {10, -5, 0}, {10, 5, 0}, {0, 5, 0});
    mesh.face_observed.assign(mesh.triangles.size(), 1);
    return mesh;
}

/// A car driving along y = 0 from x = 1 to x = 9 over 4 s.
MoverTracks one_car() {
    MoverTracks tracks;
    MoverTrack car;
    car.waypoints = {{0.0, {1.0, 0.0, 0.0}, 0.0}, {4.0, {9.0, 0.0, 0.0}, 0.0}};
    tracks.movers = {car};
    return tracks;
}

TEST(GhostArea, CountsTheQuadInsideTheSweptBoxOnly) {
    TriangleMesh pred = floor_mesh();
    pred.face_observed.clear();
    // 1 m^2 upright in the swept box (x = 5, |y| <= 0.5, z in [0.5, 1.5]): a ghost.
    add_quad(pred, {5, -0.5f, 0.5f}, {5, 0.5f, 0.5f}, {5, 0.5f, 1.5f}, {5, -0.5f, 1.5f});
    // 2 m^2 upright on the sidewalk (y = 4, far from the car's 0.9 m half width): off the static
    // scene, but no mover was there.
    add_quad(pred, {4, 4, 0.5f}, {6, 4, 0.5f}, {6, 4, 1.5f}, {4, 4, 1.5f});
    const GhostMetrics m = measure_ghost_area(pred, floor_mesh(), one_car());
    EXPECT_NEAR(m.ghost_area_m2, 1.0, kAreaRelTol * 1.0);
    EXPECT_NEAR(m.off_static_area_m2, 3.0, kAreaRelTol * 3.0);
    EXPECT_NEAR(m.ghost_share, 0.01, kAreaRelTol * 0.01);
    EXPECT_NEAR(m.ref_observed_area_m2, 100.0, 1e-9);
    EXPECT_EQ(m.num_movers, 1u);
}

TEST(GhostArea, TheStaticSceneItselfIsNoGhost) {
    // The floor under the car's path lies in its swept box but on the static scene.
    const GhostMetrics m = measure_ghost_area(floor_mesh(), floor_mesh(), one_car());
    EXPECT_EQ(m.ghost_samples, 0u);
    EXPECT_EQ(m.off_static_area_m2, 0.0);
    EXPECT_NEAR(m.pred_area_m2, 100.0, kAreaRelTol * 100.0);
}

TEST(GhostArea, SweptVolumeIsTheBoxSlidAlongThePath) {
    const MoverTrack car = one_car().movers[0];  // 4.5 x 1.8 x 1.5 m, x from 1 to 9
    const double margin_m = 0.1;
    EXPECT_TRUE(inside_swept_volume(car, {5.0, 0.0, 1.0}, margin_m));
    EXPECT_TRUE(inside_swept_volume(car, {11.2, 0.95, 1.55}, margin_m));  // front corner, grown
    EXPECT_FALSE(inside_swept_volume(car, {11.4, 0.0, 1.0}, margin_m));   // past the front
    EXPECT_FALSE(inside_swept_volume(car, {-1.4, 0.0, 1.0}, margin_m));   // behind the start
    EXPECT_FALSE(inside_swept_volume(car, {5.0, 1.05, 1.0}, margin_m));   // beside it
    EXPECT_FALSE(inside_swept_volume(car, {5.0, 0.0, 1.65}, margin_m));   // above it
    // A car turning 90 deg on the spot sweeps the disc of its half diagonal.
    MoverTrack turning = car;
    turning.waypoints = {{0.0, {0.0, 0.0, 0.0}, 0.0}, {1.0, {0.0, 0.0, 0.0}, M_PI / 2.0}};
    const double half_diagonal_m = 0.5 * std::hypot(4.5, 1.8);
    const double c = std::cos(M_PI / 4.0) * (half_diagonal_m - 0.05);
    EXPECT_TRUE(inside_swept_volume(turning, {c, c, 1.0}, 0.0));
    EXPECT_FALSE(inside_swept_volume(turning, {-c, c, 1.0}, 0.0));  // the other diagonal
}

}  // namespace
}  // namespace shine
