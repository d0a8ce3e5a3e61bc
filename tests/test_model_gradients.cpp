// Finite-difference checks of every gradient the training uses: interpolation weights, decoder
// input and parameter gradients, the Eikonal double backward, and the full per-sample loss.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "shine/core/error.hpp"
#include "shine/model/decoder.hpp"
#include "shine/model/interpolation.hpp"
#include "shine/model/neural_sdf.hpp"
#include "shine/model/sample_gradient.hpp"
#include "shine/model/sdf_loss.hpp"

using namespace shine;

namespace {
// Central differences in double-checked float arithmetic: step and tolerance chosen for float32
// kernels whose values are O(1).
constexpr double kStep = 1e-3;
constexpr double kRelTol = 2e-2;
constexpr double kAbsTol = 2e-4;

void expect_close(double analytic, double numeric, const std::string& what) {
    EXPECT_NEAR(analytic, numeric, kAbsTol + kRelTol * std::abs(numeric)) << what;
}
}  // namespace

TEST(Interpolation, WeightsSumToOneAndGradientsMatchFiniteDifferences) {
    for (const Interpolation kind : {Interpolation::kSmoothstep, Interpolation::kLinear}) {
        const float cell_m = 0.2f;
        const float t[3] = {0.3f, 0.71f, 0.45f};
        float w[8], dw[8][3];
        corner_weights_and_gradients(t, cell_m, w, dw, kind);
        double sum = 0.0;
        for (float v : w) sum += v;
        EXPECT_NEAR(sum, 1.0, 1e-6) << to_string(kind);
        for (int a = 0; a < 3; ++a) {
            float tp[3] = {t[0], t[1], t[2]}, tm[3] = {t[0], t[1], t[2]};
            const float h_m = 1e-4f;
            tp[a] += h_m / cell_m;
            tm[a] -= h_m / cell_m;
            float wp[8], wm[8];
            corner_weights(tp, wp, kind);
            corner_weights(tm, wm, kind);
            for (int c = 0; c < 8; ++c) {
                expect_close(dw[c][a], (wp[c] - wm[c]) / (2.0 * h_m),
                             std::string(to_string(kind)) + " corner " + std::to_string(c) +
                                 " axis " + std::to_string(a));
            }
        }
    }
}

TEST(Interpolation, LinearWeightsAreTrilinearAndKeepTheirSlopeAtCorners) {
    const float t[3] = {0.25f, 0.5f, 1.0f};
    float w[8], dw[8][3];
    corner_weights_and_gradients(t, 0.5f, w, dw, Interpolation::kLinear);
    EXPECT_FLOAT_EQ(w[0], 0.75f * 0.5f * 0.0f);
    EXPECT_FLOAT_EQ(w[5], 0.25f * 0.5f * 1.0f);     // x high, y low, z high
    EXPECT_FLOAT_EQ(dw[5][0], 2.0f * 0.5f * 1.0f);  // d/dx of t_x / 0.5 m
    const float corner[3] = {0.0f, 0.0f, 0.0f};
    corner_weights_and_gradients(corner, 1.0f, w, dw, Interpolation::kLinear);
    EXPECT_FLOAT_EQ(dw[1][0], 1.0f);  // smoothstep's slope is 0 here
    EXPECT_EQ(parse_interpolation("linear", "map.interpolation"), Interpolation::kLinear);
    EXPECT_THROW(parse_interpolation("cubic", "map.interpolation"), ConfigError);
}

TEST(Interpolation, IsContinuousWithZeroSlopeAtCellFaces) {
    float w0[8], w1[8], dw[8][3];
    const float t0[3] = {0.0f, 0.5f, 0.5f};
    corner_weights_and_gradients(t0, 1.0f, w0, dw);
    for (int c = 0; c < 8; ++c) EXPECT_FLOAT_EQ(dw[c][0], 0.0f);
    const float t1[3] = {1.0f, 0.5f, 0.5f};
    corner_weights(t1, w1);
    // At t = 1 the upper corners carry everything: what the next cell's lower corners get at t = 0.
    for (int c = 0; c < 8; ++c) EXPECT_FLOAT_EQ(w1[c], (c & 1) ? w0[c & ~1] : 0.0f);
}

class DecoderGradient : public ::testing::Test {
  protected:
    Decoder decoder{DecoderConfig{8, {16, 16}, 7}};
    DecoderWorkspace ws;
    float feature[8];

    void SetUp() override {
        std::mt19937 rng(3);
        std::normal_distribution<float> normal(0.0f, 0.5f);
        for (float& f : feature) f = normal(rng);
        decoder.prepare(ws);
    }
};

TEST_F(DecoderGradient, InputGradientMatchesFiniteDifferences) {
    decoder.forward(feature, ws);
    float h[8];
    decoder.input_gradient(ws, h);
    for (int l = 0; l < 8; ++l) {
        float fp[8], fm[8];
        std::copy(feature, feature + 8, fp);
        std::copy(feature, feature + 8, fm);
        fp[l] += kStep;
        fm[l] -= kStep;
        const double numeric = (decoder.forward(fp, ws) - decoder.forward(fm, ws)) / (2 * kStep);
        expect_close(h[l], numeric, "dF_" + std::to_string(l));
    }
}

TEST_F(DecoderGradient, ParameterGradientMatchesFiniteDifferences) {
    decoder.forward(feature, ws);
    float h[8];
    decoder.input_gradient(ws, h);
    std::vector<float> grads(decoder.num_params(), 0.0f);
    const float upstream = 1.7f;
    decoder.accumulate_param_gradient(ws, upstream, grads.data());
    auto& p = decoder.params();
    for (std::size_t i = 0; i < p.size(); i += 7) {
        const float saved = p[i];
        p[i] = saved + kStep;
        const double fp = decoder.forward(feature, ws);
        p[i] = saved - kStep;
        const double fm = decoder.forward(feature, ws);
        p[i] = saved;
        expect_close(grads[i], upstream * (fp - fm) / (2 * kStep), "param " + std::to_string(i));
    }
}

TEST_F(DecoderGradient, EikonalDoubleBackwardMatchesFiniteDifferences) {
    // e(params) = sum_l c_l * h_l(params) for a fixed vector c: its gradient is what
    // accumulate_input_gradient_param_gradient computes for de/dh = c.
    const float c[8] = {0.3f, -1.2f, 0.5f, 0.9f, -0.4f, 0.2f, 1.1f, -0.7f};
    auto e_of_params = [&]() {
        decoder.forward(feature, ws);
        float h[8];
        decoder.input_gradient(ws, h);
        double e = 0.0;
        for (int l = 0; l < 8; ++l) e += c[l] * h[l];
        return e;
    };
    e_of_params();
    std::vector<float> grads(decoder.num_params(), 0.0f);
    decoder.accumulate_input_gradient_param_gradient(ws, c, grads.data());
    auto& p = decoder.params();
    int checked_nonzero = 0;
    for (std::size_t i = 0; i < p.size(); ++i) {
        const float saved = p[i];
        p[i] = saved + kStep;
        const double ep = e_of_params();
        p[i] = saved - kStep;
        const double em = e_of_params();
        p[i] = saved;
        const double numeric = (ep - em) / (2 * kStep);
        expect_close(grads[i], numeric, "param " + std::to_string(i));
        if (std::abs(numeric) > 1e-3) ++checked_nonzero;
    }
    EXPECT_GT(checked_nonzero, 20) << "the check must exercise real gradients";
}

TEST(SigmoidBce, GradientMatchesFiniteDifferencesAndIsStableForLargeArguments) {
    const float sigma = 0.1f;
    for (float f : {-0.3f, -0.02f, 0.0f, 0.05f, 0.4f}) {
        const float label = 0.07f;
        const auto at = sigmoid_bce(f, label, sigma);
        const double numeric = (sigmoid_bce(f + 1e-3f, label, sigma).loss -
                                sigmoid_bce(f - 1e-3f, label, sigma).loss) /
                               2e-3;
        expect_close(at.gradient, numeric, "f=" + std::to_string(f));
    }
    const auto far = sigmoid_bce(1000.0f, -1000.0f, 0.05f);
    EXPECT_TRUE(std::isfinite(far.loss));
    EXPECT_TRUE(std::isfinite(far.gradient));
}

TEST(SampleGradient, FullLossGradientMatchesFiniteDifferences) {
    // A two-level map around a few points, and one surface sample (BCE + Eikonal).
    FeatureOctreeConfig octree_config;
    octree_config.leaf_size_m = 0.25;
    octree_config.num_levels = 2;
    octree_config.init_std = 0.3f;
    NeuralSdf sdf(octree_config, DecoderConfig{8, {16, 16}, 11});
    sdf.octree.allocate_cells(
        {Eigen::Vector3f(0.1f, 0.2f, 0.3f), Eigen::Vector3f(0.6f, 0.2f, 0.3f)});
    const RaySample sample{Eigen::Vector3f(0.13f, 0.21f, 0.34f), 0.04f, SampleKind::kSurface};
    const SampleLossConfig loss{0.1f, 0.5f};

    CellLookup lookup(sdf.octree);
    DecoderWorkspace ws;
    EncodedPoint encoded;
    SampleGradient gradient;
    std::vector<float> decoder_grads(sdf.decoder.num_params(), 0.0f);
    ASSERT_TRUE(sample_loss_gradient(sdf, lookup, ws, sample, loss, encoded, gradient,
                                     decoder_grads.data()));
    ASSERT_EQ(encoded.num_corners, 16);
    EXPECT_GT(gradient.eikonal, 0.0f);

    auto total_loss = [&]() {
        SampleGradient g;
        EncodedPoint e;
        sample_loss_gradient(sdf, lookup, ws, sample, loss, e, g, nullptr);
        return static_cast<double>(g.bce) + loss.eikonal_weight * g.eikonal;
    };
    // Feature gradient: row r gets coefficients[k] * h for each corner k reading row r.
    const int dim = sdf.octree.feature_dim();
    std::vector<double> analytic(sdf.octree.features().size(), 0.0);
    for (int k = 0; k < encoded.num_corners; ++k) {
        for (int l = 0; l < dim; ++l) {
            analytic[std::size_t(encoded.rows[k]) * dim + l] +=
                gradient.coefficients[k] * gradient.h[l];
        }
    }
    auto& features = sdf.octree.features();
    for (int k = 0; k < encoded.num_corners; k += 3) {
        for (int l = 0; l < dim; l += 3) {
            const std::size_t i = std::size_t(encoded.rows[k]) * dim + l;
            const float saved = features[i];
            features[i] = saved + kStep;
            const double lp = total_loss();
            features[i] = saved - kStep;
            const double lm = total_loss();
            features[i] = saved;
            expect_close(analytic[i], (lp - lm) / (2 * kStep), "feature " + std::to_string(i));
        }
    }
    auto& params = sdf.decoder.params();
    for (std::size_t i = 0; i < params.size(); i += 5) {
        const float saved = params[i];
        params[i] = saved + kStep;
        const double lp = total_loss();
        params[i] = saved - kStep;
        const double lm = total_loss();
        params[i] = saved;
        expect_close(decoder_grads[i], (lp - lm) / (2 * kStep),
                     "decoder param " + std::to_string(i));
    }
}
