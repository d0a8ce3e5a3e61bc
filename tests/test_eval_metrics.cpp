// Mesh evaluation protocol (accuracy, completion, Chamfer-L1, precision, recall, F-score) on
// analytic planes whose distances are known.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "shine/core/error.hpp"
#include "shine/eval/mesh_metrics.hpp"
#include "shine/eval/metrics_report.hpp"

namespace shine {
namespace {

// Two samplings of the same plane, downsampled on the 2 cm grid, differ in-plane by the centroids'
// scatter inside their voxels: 0.6 cm on average at the default density (measured), below 1.5 cm
// for nearly all points. That is the floor of every distance metric here.
constexpr double kSamplingFloorM = 0.01;  // 1 cm
// A 5 cm offset seen through that in-plane scatter: sqrt(5^2 + 1.5^2) - 5 = 0.16 cm at worst.
constexpr double kShiftM = 0.05;
constexpr double kShiftTolM = 0.002;  // 2 mm
// Shares of ~40,000 downsampled points of a 4 m x 4 m plane; band edges are blurred by one voxel
// (2 cm of 4 m = 0.5 %).
constexpr double kRatioTol = 0.01;  // 1 percentage point

/// The rectangle [x0, x1] x [y0, y1] at height z_m, triangulated on a grid of about `cell_m`.
TriangleMesh plane(double x0, double x1, double y0, double y1, double z_m, double cell_m) {
    TriangleMesh mesh;
    const int nx = static_cast<int>(std::lround((x1 - x0) / cell_m));
    const int ny = static_cast<int>(std::lround((y1 - y0) / cell_m));
    for (int j = 0; j <= ny; ++j) {
        for (int i = 0; i <= nx; ++i) {
            mesh.vertices.emplace_back(x0 + (x1 - x0) * i / nx, y0 + (y1 - y0) * j / ny, z_m);
        }
    }
    for (int j = 0; j < ny; ++j) {
        for (int i = 0; i < nx; ++i) {
            const int a = j * (nx + 1) + i;
            mesh.triangles.emplace_back(a, a + 1, a + nx + 2);
            mesh.triangles.emplace_back(a, a + nx + 2, a + nx + 1);
        }
    }
    return mesh;
}

/// The triangles of `a` and `b` in one mesh.
TriangleMesh merged(TriangleMesh a, const TriangleMesh& b) {
    const int base = static_cast<int>(a.vertices.size());
    a.vertices.insert(a.vertices.end(), b.vertices.begin(), b.vertices.end());
    for (const auto& tri : b.triangles) a.triangles.emplace_back(tri.array() + base);
    return a;
}

/// The 4 m x 4 m reference plane of most tests.
TriangleMesh reference() { return plane(0, 4, 0, 4, 0, 0.1); }

/// Marks the reference faces whose centre has x < x_m as observed.
void observe_x_below(TriangleMesh& mesh, double x_m) {
    mesh.face_observed.clear();
    for (const auto& tri : mesh.triangles) {
        const float cx =
            (mesh.vertices[tri[0]].x() + mesh.vertices[tri[1]].x() + mesh.vertices[tri[2]].x()) /
            3.0f;
        mesh.face_observed.push_back(cx < x_m ? 1 : 0);
    }
}

TEST(MeshMetrics, IdenticalMeshesScorePerfectly) {
    // Identical meshes draw identical samples: every distance is exactly zero.
    const MeshMetrics m = evaluate_meshes(reference(), reference());
    EXPECT_EQ(m.accuracy_m, 0.0);
    EXPECT_EQ(m.completion_m, 0.0);
    EXPECT_EQ(m.chamfer_l1_m, 0.0);
    EXPECT_EQ(m.fscore, 1.0);
    EXPECT_EQ(m.sample_density_per_m2, EvalConfig{}.sample_density_per_m2);
    EXPECT_NEAR(m.ref_area_m2, 16.0, 1e-9);
    // 16 m^2 of 2 cm voxels is 40,000; a few are empty (about e^-4 at four samples per voxel).
    EXPECT_GT(m.ref_points, 38000u);
    EXPECT_LE(m.ref_points, 40000u);
    EXPECT_EQ(m.pred_points, m.ref_points);
    EXPECT_EQ(m.ref_observed_points, m.ref_points);
}

TEST(MeshMetrics, SameSurfaceOtherTriangulationScoresTheSamplingFloor) {
    const MeshMetrics m = evaluate_meshes(plane(0, 4, 0, 4, 0, 0.13), reference());
    EXPECT_GT(m.accuracy_m, 0.0);  // independent samples
    EXPECT_LT(m.accuracy_m, kSamplingFloorM);
    EXPECT_LT(m.completion_m, kSamplingFloorM);
    EXPECT_EQ(m.precision, 1.0);
    EXPECT_EQ(m.completion_ratio, 1.0);
}

TEST(MeshMetrics, PlaneShiftedByFiveCentimetres) {
    const TriangleMesh pred = plane(0, 4, 0, 4, kShiftM, 0.13);
    const MeshMetrics m = evaluate_meshes(pred, reference());
    EXPECT_NEAR(m.accuracy_m, kShiftM, kShiftTolM);
    EXPECT_NEAR(m.completion_m, kShiftM, kShiftTolM);
    EXPECT_NEAR(m.chamfer_l1_m, kShiftM, kShiftTolM);
    EXPECT_GE(m.accuracy_m, kShiftM - 1e-6);  // parallel planes are never closer than the shift
    EXPECT_EQ(m.accuracy_points, m.pred_points);
    // Every distance lies in [5, 5.2) cm: all under 10 cm, none under 2 cm.
    EXPECT_EQ(m.fscore, 1.0);
    EvalConfig strict;
    strict.threshold_m = 0.02;
    const MeshMetrics s = evaluate_meshes(pred, reference(), strict);
    EXPECT_EQ(s.precision, 0.0);
    EXPECT_EQ(s.completion_ratio, 0.0);
    EXPECT_EQ(s.fscore, 0.0);
    EXPECT_EQ(s.threshold_m, 0.02);
}

TEST(MeshMetrics, PredBeyondAccuracyMaxLeavesTheAccuracyMeanOnly) {
    // Half of the prediction floats 30 cm above the reference: beyond accuracy_max_m (20 cm).
    const TriangleMesh pred = merged(plane(0, 2, 0, 4, 0, 0.13), plane(2, 4, 0, 4, 0.3, 0.13));
    const MeshMetrics m = evaluate_meshes(pred, reference());
    EXPECT_LT(m.accuracy_m, kSamplingFloorM);  // only the good half counts
    EXPECT_NEAR(static_cast<double>(m.accuracy_points) / m.pred_points, 0.5, kRatioTol);
    EXPECT_NEAR(m.precision, 0.5, kRatioTol);  // but precision sees all points
}

TEST(MeshMetrics, ThresholdAboveAccuracyMaxStillMeasuresPrecision) {
    // Half the prediction is 30 cm off (out of the 20 cm accuracy mean, within a 40 cm threshold),
    // half 1 m off (beyond both).
    EvalConfig config;
    config.threshold_m = 0.4;
    const TriangleMesh pred = merged(plane(0, 2, 0, 4, 0.3, 0.13), plane(2, 4, 0, 4, 1.0, 0.13));
    const MeshMetrics m = evaluate_meshes(pred, reference(), config);
    EXPECT_NEAR(m.precision, 0.5, kRatioTol);
    EXPECT_EQ(m.accuracy_points, 0u);
    EXPECT_EQ(m.accuracy_m, config.accuracy_max_m);  // documented value when no point qualifies
}

TEST(MeshMetrics, HalfCoverage) {
    const TriangleMesh pred = plane(0, 2, 0, 4, 0, 0.13);
    const MeshMetrics m = evaluate_meshes(pred, reference());
    EXPECT_EQ(m.precision, 1.0);
    // Reference points count as complete up to 10 cm beyond the prediction's edge at x = 2 m.
    EXPECT_NEAR(m.completion_ratio, (2.0 + 0.1) / 4.0, kRatioTol);
    // Uncovered half: distance x - 2 for x in [2, 4] averages 1 m; covered half ~0.
    EXPECT_NEAR(m.completion_m, 0.5, kRatioTol);
    EXPECT_NEAR(m.chamfer_l1_m, 0.5 * (m.accuracy_m + m.completion_m), 1e-12);
    const double p = m.precision, r = m.completion_ratio;
    EXPECT_NEAR(m.fscore, 2 * p * r / (p + r), 1e-12);

    // With a 0.5 m cap the uncovered half averages (0.5 * 0.25 + 1.5 * 0.5) / 2 = 0.4375 m.
    EvalConfig capped;
    capped.completion_cap_m = 0.5;
    const MeshMetrics c = evaluate_meshes(pred, reference(), capped);
    EXPECT_NEAR(c.completion_m, 0.5 * 0.4375, kRatioTol);
}

TEST(MeshMetrics, CompletionCountsOnlyObservedReferenceFaces) {
    TriangleMesh ref = reference();
    observe_x_below(ref, 2.0);
    // The prediction covers exactly the observed half: complete.
    const MeshMetrics m = evaluate_meshes(plane(0, 2, 0, 4, 0, 0.13), ref);
    EXPECT_NEAR(m.ref_observed_area_m2, 8.0, 1e-9);
    EXPECT_NEAR(static_cast<double>(m.ref_observed_points) / m.ref_points, 0.5, kRatioTol);
    EXPECT_GT(m.completion_ratio, 1.0 - kRatioTol);
    EXPECT_LT(m.completion_m, kSamplingFloorM);
    EXPECT_EQ(m.precision, 1.0);

    // The prediction covers only the unobserved half: precision still 1 (it is measured against
    // the whole reference), but only the 10 cm band next to it completes observed surface.
    const MeshMetrics u = evaluate_meshes(plane(2, 4, 0, 4, 0, 0.13), ref);
    EXPECT_EQ(u.precision, 1.0);
    EXPECT_NEAR(u.completion_ratio, 0.1 / 2.0, kRatioTol);
}

TEST(MeshMetrics, EmptyPredictionScoresWorstWithoutCrashing) {
    const EvalConfig config;
    const MeshMetrics m = evaluate_meshes(TriangleMesh{}, reference(), config);
    EXPECT_EQ(m.pred_points, 0u);
    EXPECT_EQ(m.precision, 0.0);
    EXPECT_EQ(m.completion_ratio, 0.0);
    EXPECT_EQ(m.fscore, 0.0);
    EXPECT_DOUBLE_EQ(m.completion_m, config.completion_cap_m);
    EXPECT_DOUBLE_EQ(m.accuracy_m, config.accuracy_max_m);
    EXPECT_GT(m.ref_points, 0u);
}

TEST(MeshMetrics, ReferenceWithoutObservedSurfaceIsADataError) {
    EXPECT_THROW(evaluate_meshes(reference(), TriangleMesh{}), DataError);
    TriangleMesh unobserved = reference();
    unobserved.face_observed.assign(unobserved.triangles.size(), 0);
    EXPECT_THROW(evaluate_meshes(reference(), unobserved), DataError);
    TriangleMesh wrong_flags = reference();
    wrong_flags.face_observed = {1, 1, 1};
    EXPECT_THROW(evaluate_meshes(reference(), wrong_flags), DataError);
}

TEST(MeshMetrics, BigScenesAreSampledWithinTheBudget) {
    EvalConfig config;
    config.max_samples_per_mesh = 10000;  // 16 m^2 reference -> 625 points/m^2
    const MeshMetrics m = evaluate_meshes(plane(0, 4, 0, 4, 0, 0.13), reference(), config);
    EXPECT_NEAR(m.sample_density_per_m2, 625.0, 1e-6);  // area sums round in the last bits
    EXPECT_LE(m.ref_points, 10000u);
    EXPECT_GT(m.ref_points, 9000u);  // 4 cm spacing: downsampling at 2 cm merges few points
    EXPECT_EQ(m.precision, 1.0);
}

TEST(MeshMetrics, RejectsOutOfRangeConfig) {
    EvalConfig config;
    config.threshold_m = 0.0;
    EXPECT_THROW(evaluate_meshes(reference(), reference(), config), ConfigError);
    config = EvalConfig{};
    config.threshold_m = 3.0;  // above completion_cap_m
    EXPECT_THROW(evaluate_meshes(reference(), reference(), config), ConfigError);
    config = EvalConfig{};
    config.max_samples_per_mesh = 0;
    EXPECT_THROW(evaluate_meshes(reference(), reference(), config), ConfigError);
}

TEST(MetricsReport, TextInCentimetresAndPercentJsonInMetres) {
    MeshMetrics m;
    m.accuracy_m = 0.0123;
    m.completion_m = 0.0456;
    m.chamfer_l1_m = 0.02895;
    m.precision = 0.9;
    m.completion_ratio = 0.8;
    m.fscore = 2 * 0.9 * 0.8 / 1.7;
    m.threshold_m = 0.1;
    m.pred_points = 17;
    const std::string text = format_metrics(m);
    EXPECT_NE(text.find("1.23 cm"), std::string::npos) << text;
    EXPECT_NE(text.find("4.56 cm"), std::string::npos) << text;
    EXPECT_NE(text.find("90.00 %"), std::string::npos) << text;
    EXPECT_NE(text.find("84.71 %"), std::string::npos) << text;

    const std::string line = metrics_to_json(m);
    EXPECT_EQ(line.find('\n'), std::string::npos);
    const auto json = nlohmann::json::parse(line);
    EXPECT_DOUBLE_EQ(json.at("accuracy_m").get<double>(), 0.0123);
    EXPECT_DOUBLE_EQ(json.at("fscore").get<double>(), m.fscore);
    EXPECT_EQ(json.at("pred_points").get<std::size_t>(), 17u);
    EXPECT_EQ(json.size(), 15u);
}

TEST(MeshMetrics, MeshesOfFarAwayMapsAreComparedInTheReferenceFrame) {
    // The same plane described from two frames 1 km apart at UTM-like coordinates, where float32
    // world coordinates would be 0.5 m coarse: the frames' shift is applied in double.
    TriangleMesh ref = reference();
    ref.origin_world_m = Eigen::Vector3d(499000.0, 5000000.0, 0.0);
    TriangleMesh pred = plane(-1000, -996, 0, 4, kShiftM, 0.13);
    pred.origin_world_m = Eigen::Vector3d(500000.0, 5000000.0, 0.0);
    const MeshMetrics m = evaluate_meshes(pred, ref);
    EXPECT_NEAR(m.accuracy_m, kShiftM, kShiftTolM);
    EXPECT_NEAR(m.completion_m, kShiftM, kShiftTolM);
    EXPECT_GT(m.fscore, 1.0 - kRatioTol);
    // The same pred with the reference's origin forgotten is 1 km away.
    pred.origin_world_m = ref.origin_world_m;
    EXPECT_EQ(evaluate_meshes(pred, ref).fscore, 0.0);
}

}  // namespace
}  // namespace shine
