// shine eval at object scale: below the street's 0.1 m threshold the protocol's sampling
// (2 cm downsampling, 1 point per cm^2) shrinks with the threshold
// (eval_config_for_threshold, mesh_metrics.hpp), so that a 1 mm F-score resolves 1 mm.
#include <gtest/gtest.h>

#include <cmath>

#include "shine/core/error.hpp"
#include "shine/eval/mesh_metrics.hpp"

namespace shine {
namespace {

/// The plane z = z_m over [0, size]^2 in cells of cell_m (two triangles each).
TriangleMesh plane(double size_m, double z_m, double cell_m) {
    TriangleMesh mesh;
    const int n = static_cast<int>(std::lround(size_m / cell_m));
    for (int j = 0; j <= n; ++j) {
        for (int i = 0; i <= n; ++i) {
            mesh.vertices.emplace_back(size_m * i / n, size_m * j / n, z_m);
        }
    }
    for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
            const int a = j * (n + 1) + i;
            mesh.triangles.emplace_back(a, a + 1, a + n + 2);
            mesh.triangles.emplace_back(a, a + n + 2, a + n + 1);
        }
    }
    return mesh;
}

TEST(MeshMetricsThreshold, StreetThresholdsKeepTheProtocol) {
    const EvalConfig street;
    for (const double threshold_m : {0.1, 0.2}) {
        const EvalConfig c = eval_config_for_threshold(threshold_m);
        EXPECT_EQ(c.threshold_m, threshold_m);
        EXPECT_EQ(c.downsample_m, street.downsample_m);
        EXPECT_EQ(c.accuracy_max_m, street.accuracy_max_m);
        EXPECT_EQ(c.completion_cap_m, street.completion_cap_m);
        EXPECT_EQ(c.sample_density_per_m2, street.sample_density_per_m2);
    }
    const EvalConfig mm = eval_config_for_threshold(0.001);
    EXPECT_DOUBLE_EQ(mm.downsample_m, 0.0002);
    EXPECT_EQ(mm.accuracy_max_m, EvalConfig{}.accuracy_max_m);  // outlier caps stay
    EXPECT_EQ(mm.completion_cap_m, EvalConfig{}.completion_cap_m);
    EXPECT_DOUBLE_EQ(mm.sample_density_per_m2, 1e8);
    EXPECT_THROW(eval_config_for_threshold(0.0), ConfigError);
}

TEST(MeshMetricsThreshold, OneMillimetreResolvesHalfAMillimetre) {
    // A 20 cm plate against the same plate 0.5 mm (within 1 mm) and 2 mm (beyond) above it.
    const TriangleMesh ref = plane(0.2, 0.0, 0.01);
    const TriangleMesh near = plane(0.2, 0.0005, 0.013);
    const TriangleMesh far = plane(0.2, 0.002, 0.013);
    const EvalConfig scaled = eval_config_for_threshold(0.001);
    const MeshMetrics m_near = evaluate_meshes(near, ref, scaled);
    const MeshMetrics m_far = evaluate_meshes(far, ref, scaled);
    EXPECT_EQ(m_near.fscore, 1.0);
    EXPECT_NEAR(m_near.chamfer_l1_m, 0.0005, 0.0001);
    EXPECT_EQ(m_far.fscore, 0.0);
    // With the street's 2 cm downsampling the 1 mm threshold cannot tell them apart as well:
    // the centroids of 2 cm voxels scatter by millimetres.
    EvalConfig street;
    street.threshold_m = 0.001;
    const MeshMetrics street_near = evaluate_meshes(near, ref, street);
    EXPECT_LT(street_near.fscore, m_near.fscore);
}

}  // namespace
}  // namespace shine
