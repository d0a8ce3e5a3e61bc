// Tiled evaluation (a city's scale): on hand-made scenes larger than a tile the combined figures
// are the area shares the whole-scene protocol gives, a tile's border costs nothing, ghosts add
// up, and bad settings are refused.
#include <gtest/gtest.h>

#include "mesh_test_support.hpp"
#include "shine/core/error.hpp"
#include "shine/eval/mesh_metrics.hpp"
#include "shine/eval/tiled_evaluation.hpp"

namespace shine {
namespace {

using mesh_test::add_quad;

/// A floor x in [x0, x1], y in [-5, 5] at height z, in squares of 0.5 m.
TriangleMesh floor_mesh(float x0, float x1, float z) {
    TriangleMesh mesh;
    constexpr float kCellM = 0.5f;
    const int nx = static_cast<int>((x1 - x0) / kCellM + 0.5f);
    for (int i = 0; i < nx; ++i) {
        for (int j = 0; j < 20; ++j) {
            const float xa = x0 + i * kCellM, xb = xa + kCellM;
            const float ya = -5.0f + j * kCellM, yb = ya + kCellM;
            add_quad(mesh, {xa, ya, z}, {xb, ya, z}, {xb, yb, z}, {xa, yb, z});
        }
    }
    return mesh;
}

/// Appends `part` to `mesh`.
void append(TriangleMesh& mesh, const TriangleMesh& part) {
    const int offset = static_cast<int>(mesh.vertices.size());
    mesh.vertices.insert(mesh.vertices.end(), part.vertices.begin(), part.vertices.end());
    for (const Eigen::Vector3i& t : part.triangles) {
        mesh.triangles.push_back(t + Eigen::Vector3i::Constant(offset));
    }
}

/// The reference: a floor 40 m x 10 m, all observed.
TriangleMesh reference() {
    TriangleMesh ref = floor_mesh(0, 40, 0);
    ref.face_observed.assign(ref.triangles.size(), 1);
    return ref;
}

/// Tiles of `tile_m`, sampled at 1 point per 4 cm^2 (fast; the 10 cm threshold still holds).
TiledEvalConfig tiles_of(double tile_m) {
    TiledEvalConfig config;
    config.tile_m = tile_m;
    config.eval.sample_density_per_m2 = 2500.0;
    return config;
}

TEST(TiledEvaluation, GivesTheAreaSharesOfTheWholeScene) {
    // The prediction: the floor, but its last quarter (x > 30 m) 0.3 m too high, so a quarter of
    // it is off and a quarter of the reference is missed. Tiles of 12 m do not fall on x = 30.
    TriangleMesh pred = floor_mesh(0, 30, 0);
    append(pred, floor_mesh(30, 40, 0.3f));
    const TiledEvaluation tiled = evaluate_meshes_tiled(pred, reference(), tiles_of(12.0));
    const MeshMetrics whole = evaluate_meshes(pred, reference(), tiles_of(12.0).eval);
    EXPECT_EQ(tiled.tiles_scored, 4u);
    EXPECT_NEAR(tiled.metrics.precision, 0.75, 0.01);
    EXPECT_NEAR(tiled.metrics.completion_ratio, 0.75, 0.01);
    EXPECT_NEAR(tiled.metrics.fscore, 0.75, 0.01);
    EXPECT_NEAR(tiled.metrics.precision, whole.precision, 0.01);
    EXPECT_NEAR(tiled.metrics.completion_ratio, whole.completion_ratio, 0.01);
    EXPECT_NEAR(tiled.metrics.pred_area_m2, 400.0, 0.1);
    EXPECT_NEAR(tiled.metrics.ref_observed_area_m2, 400.0, 1e-6);
    EXPECT_NEAR(tiled.metrics.ref_area_m2, 400.0, 1e-6);
    // Every tile is sampled at the target density.
    EXPECT_EQ(tiled.metrics.sample_density_per_m2, 2500.0);
    EXPECT_EQ(tiled.unscored_pred_area_m2, 0.0);
}

TEST(TiledEvaluation, ATilesBorderCostsNothing) {
    // The prediction equals the reference; its triangles near a border find the reference across
    // it (the margin), and every observed face is counted once. The accuracy is the sampling's
    // own scatter (the tiles of the two meshes draw different samples; measured 1.1 cm).
    const TiledEvaluation tiled = evaluate_meshes_tiled(reference(), reference(), tiles_of(3.0));
    EXPECT_EQ(tiled.tiles_scored, 56u);  // 14 x 4 tiles of 3 m over the 40 m x 10 m floor
    EXPECT_EQ(tiled.metrics.precision, 1.0);
    EXPECT_EQ(tiled.metrics.completion_ratio, 1.0);
    EXPECT_NEAR(tiled.metrics.ref_observed_area_m2, 400.0, 1e-6);
    EXPECT_LT(tiled.metrics.accuracy_m, 0.015);
}

TEST(TiledEvaluation, GhostsOfTheTilesAddUp) {
    // Two 1 m^2 quads inside the swept box of a car that drives along y = 0 over the whole floor,
    // in different tiles, and a 2 m^2 quad away from it.
    MoverTracks tracks;
    MoverTrack car;
    car.waypoints = {{0.0, {2.0, 0.0, 0.0}, 0.0}, {10.0, {38.0, 0.0, 0.0}, 0.0}};
    tracks.movers = {car};
    TriangleMesh pred = floor_mesh(0, 40, 0);
    add_quad(pred, {8, -0.5f, 0.5f}, {8, 0.5f, 0.5f}, {8, 0.5f, 1.5f}, {8, -0.5f, 1.5f});
    add_quad(pred, {28, -0.5f, 0.5f}, {28, 0.5f, 0.5f}, {28, 0.5f, 1.5f}, {28, -0.5f, 1.5f});
    add_quad(pred, {16, 3.5f, 0.5f}, {18, 3.5f, 0.5f}, {18, 3.5f, 1.5f}, {16, 3.5f, 1.5f});
    const TiledEvaluation tiled = evaluate_meshes_tiled(pred, reference(), tiles_of(12.0), &tracks);
    EXPECT_NEAR(tiled.ghost.ghost_area_m2, 2.0, 0.03 * 2.0);
    EXPECT_NEAR(tiled.ghost.off_static_area_m2, 4.0, 0.03 * 4.0);
    EXPECT_NEAR(tiled.ghost.ghost_share, 2.0 / 400.0, 0.03 * 2.0 / 400.0);
    EXPECT_EQ(tiled.ghost.num_movers, 1u);
    // Without movers there is no ghost measure.
    EXPECT_EQ(evaluate_meshes_tiled(pred, reference(), tiles_of(12.0)).ghost.ghost_samples, 0u);
}

TEST(TiledEvaluation, RefusesBadSettingsAndUnobservedReferences) {
    EXPECT_THROW(evaluate_meshes_tiled(reference(), reference(), tiles_of(0.0)), ConfigError);
    EXPECT_THROW(evaluate_meshes_tiled(reference(), reference(), tiles_of(-5.0)), ConfigError);
    EXPECT_THROW(evaluate_meshes_tiled(reference(), reference(), tiles_of(1e-5)), ConfigError);
    TiledEvalConfig no_margin = tiles_of(30.0);
    no_margin.margin_m = 0.0;
    EXPECT_THROW(evaluate_meshes_tiled(reference(), reference(), no_margin), ConfigError);
    TriangleMesh unobserved = reference();
    unobserved.face_observed.assign(unobserved.triangles.size(), 0);
    EXPECT_THROW(evaluate_meshes_tiled(reference(), unobserved, tiles_of(30.0)), DataError);
    TriangleMesh broken = reference();
    broken.triangles.push_back({0, 1, static_cast<int>(broken.vertices.size())});
    broken.face_observed.push_back(1);
    EXPECT_THROW(evaluate_meshes_tiled(reference(), broken, tiles_of(30.0)), DataError);
    // Predicted surface where nothing was observed is reported, not scored.
    TriangleMesh pred = reference();
    pred.face_observed.clear();
    append(pred, floor_mesh(100, 110, 0));
    TriangleMesh ref = reference();
    append(ref, floor_mesh(100, 110, 0));
    ref.face_observed.resize(ref.triangles.size(), 0);
    const TiledEvaluation tiled = evaluate_meshes_tiled(pred, ref, tiles_of(30.0));
    EXPECT_NEAR(tiled.unscored_pred_area_m2, 100.0, 1e-3);
    EXPECT_EQ(tiled.metrics.precision, 1.0);
}

}  // namespace
}  // namespace shine
