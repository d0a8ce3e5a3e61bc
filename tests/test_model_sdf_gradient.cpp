// The neural SDF's analytic spatial gradient (J^T h) against central differences of its value, on
// a randomly initialised small map; values equal NeuralSdf::query's.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "shine/core/cpu_features.hpp"
#include "shine/model/feature_encoding.hpp"
#include "shine/model/neural_sdf.hpp"
#include "shine/model/sdf_gradient.hpp"

using namespace shine;

namespace {

constexpr float kStepM = 1e-3f;   // central-difference step: 1 mm in 0.25 m cells
constexpr double kAbsTol = 2e-3;  // per metre: float rounding of values ~0.1 over 2 mm
constexpr double kRelTol = 2e-2;  // truncation and the odd ReLU kink within the step

NeuralSdf random_map(FeaturePrecision precision = FeaturePrecision::kFloat32) {
    FeatureOctreeConfig octree;
    octree.feature_precision = precision;
    octree.leaf_size_m = 0.25;
    octree.num_levels = 2;
    octree.init_std = 0.3f;
    NeuralSdf sdf(octree, DecoderConfig{8, {16, 16}, 5});
    std::vector<Eigen::Vector3f> seeds;
    for (float x = 0.05f; x < 1.0f; x += 0.2f) {
        for (float y = 0.05f; y < 1.0f; y += 0.2f) seeds.emplace_back(x, y, 0.1f);
    }
    sdf.octree.allocate_cells(seeds);
    return sdf;
}

}  // namespace

TEST(SdfGradient, MatchesCentralDifferencesAndQueryValues) {
    const NeuralSdf sdf = random_map();
    std::mt19937 rng(21);
    std::uniform_real_distribution<float> u(0.06f, 0.94f);
    std::uniform_real_distribution<float> uz(0.02f, 0.22f);
    std::vector<Eigen::Vector3f> points;
    for (int i = 0; i < 200; ++i) points.emplace_back(u(rng), u(rng), uz(rng));

    std::vector<float> value;
    std::vector<Eigen::Vector3f> gradient;
    std::vector<std::uint8_t> valid;
    query_sdf_and_gradient(sdf, points, QueryMask::kLevel0, value, gradient, valid);

    std::vector<float> reference;
    std::vector<std::uint8_t> reference_valid;
    sdf.query(points, QueryMask::kLevel0, reference, reference_valid);
    EXPECT_EQ(valid, reference_valid);
    EXPECT_EQ(value, reference);  // bit for bit

    // Central differences through query(): +-step along each axis, in one batch.
    std::vector<Eigen::Vector3f> shifted;
    for (const auto& p : points) {
        for (int a = 0; a < 3; ++a) {
            shifted.push_back(p + kStepM * Eigen::Vector3f::Unit(a));
            shifted.push_back(p - kStepM * Eigen::Vector3f::Unit(a));
        }
    }
    std::vector<float> shifted_value;
    std::vector<std::uint8_t> shifted_valid;
    sdf.query(shifted, QueryMask::kLevel0, shifted_value, shifted_valid);
    // The decoder's ReLUs make the SDF piecewise smooth: where a kink lies within the step, the
    // central difference mixes two slopes, and the analytic derivative (that of the point's own
    // side) equals one of the one-sided differences instead. Each derivative must match the
    // central difference or, at a kink, a one-sided one; and kinks must stay the exception.
    const auto close = [](double analytic, double numeric) {
        return std::abs(analytic - numeric) <= kAbsTol + kRelTol * std::abs(numeric);
    };
    int checked = 0, central = 0;
    double gradient_norm_sum = 0.0;
    for (std::size_t i = 0; i < points.size(); ++i) {
        if (!valid[i]) continue;
        gradient_norm_sum += gradient[i].norm();
        for (int a = 0; a < 3; ++a) {
            const std::size_t k = 6 * i + 2 * std::size_t(a);
            if (!shifted_valid[k] || !shifted_valid[k + 1]) continue;
            const double plus = shifted_value[k], minus = shifted_value[k + 1], at = value[i];
            const double numeric = (plus - minus) / (2.0 * kStepM);
            const double forward = (plus - at) / kStepM, backward = (at - minus) / kStepM;
            ++checked;
            if (close(gradient[i][a], numeric)) {
                ++central;
            } else {
                EXPECT_TRUE(close(gradient[i][a], forward) || close(gradient[i][a], backward))
                    << "point " << i << " axis " << a << ": analytic " << gradient[i][a]
                    << ", central " << numeric << ", forward " << forward << ", backward "
                    << backward;
            }
        }
    }
    EXPECT_GE(checked, 500);  // most of the 200 x 3 derivatives are inside the map
    EXPECT_GE(central, checked * 9 / 10) << "kinks within 1 mm of more than 10 % of the points";
    EXPECT_GT(gradient_norm_sum / checked * 3, 0.05);  // a random map has real slopes
}

TEST(SdfGradient, EightAtATimeEqualsOnePointAtATime) {
    // The query evaluates the decoder for up to eight points at once; each point's value and
    // gradient must be those of the plain per-point path: forward(), input_gradient() and the
    // encoding's Jacobian. Points outside the map are mixed in, so that the groups of eight
    // skip points and the last one is partial. Float32 and float16 feature tables.
    for (const FeaturePrecision precision :
         {FeaturePrecision::kFloat32, FeaturePrecision::kFloat16}) {
        const NeuralSdf sdf = random_map(precision);
        std::mt19937 rng(5);
        std::uniform_real_distribution<float> u(-0.3f, 1.3f);
        std::vector<Eigen::Vector3f> points;
        for (int i = 0; i < 203; ++i) points.emplace_back(u(rng), u(rng), 0.1f + 0.2f * u(rng));
        std::vector<float> value;
        std::vector<Eigen::Vector3f> gradient;
        std::vector<std::uint8_t> valid;
        query_sdf_and_gradient(sdf, points, QueryMask::kAnyLevel, value, gradient, valid);

        const int dim = sdf.octree.feature_dim();
        const FeatureTableView features = sdf.octree.features().data();
        CellLookup lookup(sdf.octree);
        DecoderWorkspace ws;
        sdf.decoder.prepare(ws);
        int inside = 0, outside = 0;
        for (std::size_t i = 0; i < points.size(); ++i) {
            EncodedPoint encoded;
            encode_point(lookup, sdf.octree, points[i], true, encoded);
            if (!encoded.valid()) {
                ++outside;
                EXPECT_EQ(valid[i], 0) << "point " << i;
                continue;
            }
            ++inside;
            ASSERT_EQ(valid[i], 1) << "point " << i;
            float feature[kMaxFeatureDim], h[kMaxFeatureDim], jacobian[3 * kMaxFeatureDim];
            gather_feature(encoded, features, dim, feature);
            const float f = sdf.decoder.forward(feature, ws);
            sdf.decoder.input_gradient(ws, h);
            feature_jacobian(encoded, features, dim, jacobian);
            Eigen::Vector3f g = Eigen::Vector3f::Zero();
            for (int l = 0; l < dim; ++l) {
                for (int a = 0; a < 3; ++a) g[a] += jacobian[l * 3 + a] * h[l];
            }
#if defined(__FMA__)
            EXPECT_NEAR(value[i], f, 1e-5f);
            EXPECT_LT((gradient[i] - g).norm(), 1e-4f * (1.0f + g.norm()));
#else
            EXPECT_EQ(value[i], f) << "point " << i;  // bit for bit
            EXPECT_EQ(gradient[i], g) << "point " << i;
#endif
        }
        EXPECT_GT(inside, 50);
        EXPECT_GT(outside, 20);
    }
}

TEST(SdfGradient, TheAvxGatherOfAFloat16MapEqualsThePlainOne) {
    // gather_feature_and_jacobian on a float16 table of 8 features has an AVX/F16C version; its
    // feature and Jacobian must be the plain version's bit for bit (a no-op where the CPU lacks
    // AVX and F16C: both runs take the plain path).
    const NeuralSdf sdf = random_map(FeaturePrecision::kFloat16);
    ASSERT_EQ(sdf.octree.feature_dim(), 8);
    const FeatureTableView features = sdf.octree.features().data();
    CellLookup lookup(sdf.octree);
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(-0.3f, 1.3f);
    int inside = 0;
    for (int i = 0; i < 300; ++i) {
        const Eigen::Vector3f p(u(rng), u(rng), 0.1f + 0.2f * u(rng));
        EncodedPoint encoded;
        encode_point(lookup, sdf.octree, p, true, encoded);
        if (!encoded.valid()) continue;
        ++inside;
        float feature[2][kMaxFeatureDim], jacobian[2][3 * kMaxFeatureDim];
        for (int simd = 0; simd < 2; ++simd) {
            set_simd_enabled(simd == 1);
            gather_feature_and_jacobian(encoded, features, 8, feature[simd], jacobian[simd]);
        }
        set_simd_enabled(true);
        for (int l = 0; l < 8; ++l) {
            EXPECT_EQ(feature[0][l], feature[1][l]) << "point " << i;
            for (int a = 0; a < 3; ++a) {
                EXPECT_EQ(jacobian[0][l * 3 + a], jacobian[1][l * 3 + a]) << "point " << i;
            }
        }
    }
    EXPECT_GT(inside, 50);
}

TEST(SdfGradient, PointsOutsideTheMapAreInvalidWithZeroGradient) {
    const NeuralSdf sdf = random_map();
    const std::vector<Eigen::Vector3f> points = {{50, 50, 50}, {0.5f, 0.5f, 0.1f}};
    std::vector<float> value;
    std::vector<Eigen::Vector3f> gradient;
    std::vector<std::uint8_t> valid;
    query_sdf_and_gradient(sdf, points, QueryMask::kAnyLevel, value, gradient, valid);
    ASSERT_EQ(valid.size(), 2u);
    EXPECT_EQ(valid[0], 0);
    EXPECT_EQ(value[0], 0.0f);
    EXPECT_EQ(gradient[0], Eigen::Vector3f::Zero());
    EXPECT_EQ(valid[1], 1);
    EXPECT_NE(gradient[1], Eigen::Vector3f::Zero());
}

// The remembered cells (QueryCellMemory) give the same bits as fresh look-ups, over queries whose
// points move a little (mostly staying in their cells, as between registration iterations), a lot
// (into other cells) and out of the map, on float32 and float16 maps.
TEST(SdfGradient, RememberedCellsGiveTheSameBitsAsFreshLookups) {
    for (const FeaturePrecision precision :
         {FeaturePrecision::kFloat32, FeaturePrecision::kFloat16}) {
        const NeuralSdf sdf = random_map(precision);
        std::mt19937 rng(5);
        std::uniform_real_distribution<float> u(-0.1f, 1.1f);  // some points outside the map
        std::uniform_real_distribution<float> uz(-0.05f, 0.3f);
        std::normal_distribution<float> small_m(0.0f, 0.003f);  // stays in most cells
        std::normal_distribution<float> large_m(0.0f, 0.2f);    // crosses cells
        std::vector<Eigen::Vector3f> points;
        for (int i = 0; i < 700; ++i) points.emplace_back(u(rng), u(rng), uz(rng));
        QueryCellMemory memory;
        int crossed = 0;
        for (int round = 0; round < 6; ++round) {
            std::vector<float> value, value_fresh;
            std::vector<Eigen::Vector3f> gradient, gradient_fresh;
            std::vector<std::uint8_t> valid, valid_fresh;
            query_sdf_and_gradient(sdf, points, QueryMask::kAnyLevel, value, gradient, valid,
                                   &memory);
            query_sdf_and_gradient(sdf, points, QueryMask::kAnyLevel, value_fresh, gradient_fresh,
                                   valid_fresh);
            ASSERT_EQ(valid, valid_fresh) << "round " << round;
            ASSERT_EQ(value, value_fresh) << "round " << round;  // bit for bit
            ASSERT_EQ(gradient, gradient_fresh) << "round " << round;
            for (auto& p : points) {
                const Eigen::Vector3f before = p;
                for (int a = 0; a < 3; ++a) p[a] += round % 2 == 0 ? small_m(rng) : large_m(rng);
                crossed += (before / 0.25f).array().floor().matrix() !=
                                   (p / 0.25f).array().floor().matrix()
                               ? 1
                               : 0;
            }
        }
        EXPECT_GT(crossed, 500);  // the memory was put to the test: many points changed cells
        // Fewer points than remembered: the memory starts again rather than reading stale cells.
        points.resize(300);
        std::vector<float> value, value_fresh;
        std::vector<Eigen::Vector3f> gradient, gradient_fresh;
        std::vector<std::uint8_t> valid, valid_fresh;
        query_sdf_and_gradient(sdf, points, QueryMask::kLevel0, value, gradient, valid, &memory);
        query_sdf_and_gradient(sdf, points, QueryMask::kLevel0, value_fresh, gradient_fresh,
                               valid_fresh);
        EXPECT_EQ(valid, valid_fresh);
        EXPECT_EQ(value, value_fresh);
        EXPECT_EQ(gradient, gradient_fresh);
        EXPECT_EQ(memory.cells.size(), 300u * sdf.octree.num_levels());
    }
}
