// The batched kernels against the per-sample reference: the batched decoder
// (batched_decoder.hpp) against Decoder's per-sample calls, and batch_loss_gradient
// (batch_gradient.hpp) against sample_loss_gradient, to float tolerance.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>

#include "shine/core/cpu_features.hpp"
#include "shine/model/batch_gradient.hpp"
#include "shine/model/batched_decoder.hpp"
#include "shine/model/decoder.hpp"
#include "shine/model/sample_gradient.hpp"

using namespace shine;

namespace {
// Batched and per-sample sums differ only in the order of float additions over O(1) values.
constexpr float kAbsTol = 1e-5f;
constexpr float kRelTol = 1e-4f;

void expect_float_close(float batched, float reference, const std::string& what) {
    EXPECT_NEAR(batched, reference, kAbsTol + kRelTol * std::abs(reference)) << what;
}
}  // namespace

TEST(BatchedDecoder, EqualsPerSampleForwardInputAndParameterGradients) {
    const Decoder decoder(DecoderConfig{8, {32, 32}, 19});
    constexpr int kBatch = 37;
    std::mt19937 rng(5);
    std::normal_distribution<float> normal(0.0f, 0.5f);
    DecoderBatch batch;
    prepare_batch(decoder, kBatch, batch);
    Eigen::RowVectorXf grad_output(kBatch);
    Eigen::MatrixXf grad_h(8, kBatch);
    for (int b = 0; b < kBatch; ++b) {
        for (int l = 0; l < 8; ++l) batch.features()(l, b) = normal(rng);
        grad_output[b] = normal(rng);
        for (int l = 0; l < 8; ++l) grad_h(l, b) = normal(rng);
    }
    forward_batch(decoder, batch);
    input_gradient_batch(decoder, batch);
    std::vector<float> batched(decoder.num_params(), 0.0f);
    accumulate_param_gradient_batch(decoder, batch, grad_output, &grad_h, batched.data());
    std::vector<float> bce_only(decoder.num_params(), 0.0f);
    accumulate_param_gradient_batch(decoder, batch, grad_output, nullptr, bce_only.data());

    std::vector<float> reference(decoder.num_params(), 0.0f);
    std::vector<float> reference_bce(decoder.num_params(), 0.0f);
    DecoderWorkspace ws;
    decoder.prepare(ws);
    int active_masks = 0;
    for (int b = 0; b < kBatch; ++b) {
        const float f = decoder.forward(batch.features().col(b).data(), ws);
        expect_float_close(batch.output()(0, b), f, "f of sample " + std::to_string(b));
        float h[8];
        decoder.input_gradient(ws, h);
        for (int l = 0; l < 8; ++l) {
            expect_float_close(batch.input_gradient(l, b), h[l],
                               "h of sample " + std::to_string(b));
            active_masks += h[l] != 0.0f;
        }
        decoder.accumulate_param_gradient(ws, grad_output[b], reference.data());
        decoder.accumulate_param_gradient(ws, grad_output[b], reference_bce.data());
        decoder.accumulate_input_gradient_param_gradient(ws, grad_h.col(b).data(),
                                                         reference.data());
    }
    EXPECT_GT(active_masks, 8 * kBatch / 2);
    for (std::size_t i = 0; i < reference.size(); ++i) {
        expect_float_close(batched[i], reference[i], "param " + std::to_string(i));
        expect_float_close(bce_only[i], reference_bce[i], "param (BCE only) " + std::to_string(i));
    }
}

TEST(BatchGradient, EqualsPerSampleLossGradientIncludingSamplesOutsideTheMap) {
    FeatureOctreeConfig octree_config;
    octree_config.leaf_size_m = 0.25;
    octree_config.num_levels = 3;
    octree_config.init_std = 0.3f;
    NeuralSdf sdf(octree_config, DecoderConfig{8, {32, 32}, 11});
    std::vector<Eigen::Vector3f> points;
    for (int i = 0; i < 20; ++i) points.emplace_back(0.1f * i, 0.05f * i, 0.3f);
    sdf.octree.allocate_cells(points);

    std::mt19937 rng(9);
    std::uniform_real_distribution<float> coordinate(-0.5f, 2.5f);
    std::uniform_real_distribution<float> label(-0.2f, 0.2f);
    std::vector<RaySample> samples;
    for (int i = 0; i < 200; ++i) {
        samples.push_back({Eigen::Vector3f(coordinate(rng), 0.4f * coordinate(rng), 0.3f),
                           label(rng), i % 2 ? SampleKind::kSurface : SampleKind::kFreeSpace});
    }
    const SampleLossConfig config{0.05f, 0.1f};
    CellLookup lookup(sdf.octree);
    BatchGradient batch;
    std::vector<float> batched_decoder(sdf.decoder.num_params(), 0.0f);
    batch_loss_gradient(sdf, lookup, samples.data(), samples.size(), config, batch,
                        batched_decoder.data());

    std::vector<float> reference_decoder(sdf.decoder.num_params(), 0.0f);
    DecoderWorkspace ws;
    EncodedPoint encoded;
    SampleGradient gradient;
    std::size_t b = 0;
    double bce_sum = 0.0, eikonal_sum = 0.0;
    for (std::size_t i = 0; i < samples.size(); ++i) {
        if (!sample_loss_gradient(sdf, lookup, ws, samples[i], config, encoded, gradient,
                                  reference_decoder.data())) {
            continue;
        }
        ASSERT_LT(b, batch.num_valid());
        ASSERT_EQ(batch.sample[b], i);
        ASSERT_EQ(batch.corners[b], encoded.num_corners);
        bce_sum += gradient.bce;
        eikonal_sum += gradient.eikonal;
        expect_float_close(batch.sdf_m[b], gradient.sdf_m, "f");
        for (int l = 0; l < 8; ++l) expect_float_close(batch.h(b)[l], gradient.h[l], "h");
        for (int k = 0; k < encoded.num_corners; ++k) {
            EXPECT_EQ(batch.rows[b * batch.corner_stride + k], encoded.rows[k]);
            expect_float_close(batch.coefficients[b * batch.corner_stride + k],
                               gradient.coefficients[k], "coefficient");
        }
        ++b;
    }
    EXPECT_EQ(b, batch.num_valid());
    EXPECT_GT(b, 40u);
    EXPECT_LT(b, samples.size());  // some samples fall outside the map
    EXPECT_NEAR(batch.bce_sum, bce_sum, 1e-4 * bce_sum);
    EXPECT_NEAR(batch.eikonal_sum, eikonal_sum, 1e-4 * eikonal_sum + 1e-6);
    EXPECT_GT(eikonal_sum, 0.0);
    for (std::size_t i = 0; i < reference_decoder.size(); ++i) {
        EXPECT_NEAR(batched_decoder[i], reference_decoder[i],
                    1e-4f + 1e-4f * std::abs(reference_decoder[i]))
            << "decoder param " << i;
    }
}

// The AVX/F16C gather of a float16 map (a corner's 8 features in one load and conversion) does
// the plain gather's operations in the same order: every output equal bit for bit.
TEST(BatchGradient, Float16FastGatherEqualsPlainGatherBitForBit) {
    FeatureOctreeConfig octree_config;
    octree_config.leaf_size_m = 0.25;
    octree_config.num_levels = 3;
    octree_config.init_std = 0.3f;
    octree_config.feature_precision = FeaturePrecision::kFloat16;
    NeuralSdf sdf(octree_config, DecoderConfig{8, {32, 32}, 11});
    std::vector<Eigen::Vector3f> points;
    for (int i = 0; i < 40; ++i) points.emplace_back(0.05f * i, 0.03f * i, 0.3f + 0.01f * i);
    sdf.octree.allocate_cells(points);
    ASSERT_EQ(sdf.octree.feature_precision(), FeaturePrecision::kFloat16);

    std::mt19937 rng(21);
    std::uniform_real_distribution<float> coordinate(-0.5f, 2.5f);
    std::uniform_real_distribution<float> label(-0.2f, 0.2f);
    std::vector<RaySample> samples;
    for (int i = 0; i < 500; ++i) {
        samples.push_back({Eigen::Vector3f(coordinate(rng), 0.6f * coordinate(rng),
                                           0.2f + 0.2f * coordinate(rng)),
                           label(rng), i % 3 ? SampleKind::kSurface : SampleKind::kFreeSpace});
    }
    const SampleLossConfig config{0.05f, 0.1f};
    BatchGradient batches[2];
    std::vector<float> decoder_grads[2];
    for (int fast = 0; fast < 2; ++fast) {
        set_simd_enabled(fast == 1);
        CellLookup lookup(sdf.octree);
        decoder_grads[fast].assign(sdf.decoder.num_params(), 0.0f);
        batch_loss_gradient(sdf, lookup, samples.data(), samples.size(), config, batches[fast],
                            decoder_grads[fast].data());
    }
    set_simd_enabled(true);
    const BatchGradient& plain = batches[0];
    const BatchGradient& fast = batches[1];
    ASSERT_EQ(plain.num_valid(), fast.num_valid());
    ASSERT_GT(plain.num_valid(), 100u);
    const auto same_bits = [](const float* a, const float* b, std::size_t n) {
#if defined(__FMA__)
        // A build for a CPU with FMA (SHINE_NATIVE): Eigen fuses multiply-adds, the AVX kernels
        // may not; equal to float rounding.
        for (std::size_t i = 0; i < n; ++i) {
            if (!(std::abs(a[i] - b[i]) <= kAbsTol + kRelTol * std::abs(b[i]))) return false;
        }
        return true;
#else
        return std::memcmp(a, b, n * sizeof(float)) == 0;
#endif
    };
    const std::size_t n = plain.num_valid();
    const Eigen::Index B = static_cast<Eigen::Index>(n);
    int eikonal_samples = 0;
    for (std::size_t b = 0; b < n; ++b) eikonal_samples += plain.eikonal[b];
    EXPECT_GT(eikonal_samples, 50);
    EXPECT_TRUE(same_bits(plain.decoder.activations[0].data(), fast.decoder.activations[0].data(),
                          std::size_t(8 * B)))
        << "features F";
    for (std::size_t b = 0; b < n; ++b) {
        if (!plain.eikonal[b]) continue;
        EXPECT_TRUE(same_bits(plain.jacobian.data() + b * 24, fast.jacobian.data() + b * 24, 24))
            << "Jacobian of sample " << b;
    }
    EXPECT_TRUE(same_bits(plain.sdf_m.data(), fast.sdf_m.data(), n)) << "f";
    EXPECT_TRUE(same_bits(plain.decoder.input_gradient.data(), fast.decoder.input_gradient.data(),
                          std::size_t(8 * B)))
        << "h";
    EXPECT_TRUE(same_bits(plain.coefficients.data(), fast.coefficients.data(),
                          n * std::size_t(plain.corner_stride)))
        << "coefficients";
#if defined(__FMA__)
    EXPECT_NEAR(fast.bce_sum, plain.bce_sum, 1e-5 * std::abs(plain.bce_sum));
    EXPECT_NEAR(fast.eikonal_sum, plain.eikonal_sum, 1e-5 * std::abs(plain.eikonal_sum));
#else
    EXPECT_EQ(plain.bce_sum, fast.bce_sum);
    EXPECT_EQ(plain.eikonal_sum, fast.eikonal_sum);
#endif
    EXPECT_TRUE(
        same_bits(decoder_grads[0].data(), decoder_grads[1].data(), decoder_grads[0].size()))
        << "decoder gradient";
}

// The AVX kernels of the layers' products (hidden layers of 8, 16, 24 or 32 units, and the input
// gradient to 8 to 32 features) do Eigen's multiplications and additions in Eigen's order, then
// its bias, ReLU and mask: every activation, upstream gradient and input gradient equal bit for
// bit with the kernels switched off. Shapes the kernels do not take (5 features, 40 units) fall
// back to Eigen in the same pass; batch sizes cover the odd last column of the kernels' pairs.
TEST(BatchedDecoder, AvxLayerProductsEqualEigenBitForBit) {
    set_simd_enabled(true);
    if (!use_avx_f16c()) GTEST_SKIP() << "the CPU has no AVX";
    const DecoderConfig shapes[] = {
        {8, {32, 32}, 3}, {8, {16, 24}, 4}, {16, {32}, 5}, {5, {32, 8}, 6}, {8, {40, 32}, 7}};
    std::mt19937 rng(9);
    std::normal_distribution<float> normal(0.0f, 0.7f);
    for (const DecoderConfig& shape : shapes) {
        Decoder decoder(shape);
        // Biases that are not zero, so that the ReLU masks differ from the products' signs.
        for (float& p : decoder.params()) p += 0.1f * normal(rng);
        const std::vector<int>& dims = decoder.layer_dims();
        const int K = decoder.num_layers();
        for (const int batch_size : {1, 2, 3, 8, 37, 1001}) {
            DecoderBatch batches[2];
            Eigen::MatrixXf features(dims[0], batch_size);
            for (int b = 0; b < batch_size; ++b) {
                for (int l = 0; l < dims[0]; ++l) {
                    // Some exact zeros of both signs among the features.
                    const int pick = (b * 7 + l) % 23;
                    features(l, b) = pick == 0 ? 0.0f : pick == 1 ? -0.0f : normal(rng);
                }
            }
            for (int fast = 0; fast < 2; ++fast) {
                set_simd_enabled(fast == 1);
                prepare_batch(decoder, batch_size, batches[fast]);
                batches[fast].features() = features;
                forward_batch(decoder, batches[fast]);
                input_gradient_batch(decoder, batches[fast]);
            }
            set_simd_enabled(true);
            const std::string where = "decoder " + std::to_string(dims[0]) + "-" +
                                      std::to_string(dims[1]) + ", batch " +
                                      std::to_string(batch_size);
            const auto expect_same = [&](const Eigen::MatrixXf& eigen, const Eigen::MatrixXf& avx,
                                         const std::string& what) {
                ASSERT_EQ(eigen.rows(), avx.rows()) << what << ", " << where;
                ASSERT_EQ(eigen.cols(), avx.cols()) << what << ", " << where;
#if defined(__FMA__)
                // A build for a CPU with FMA (SHINE_NATIVE): Eigen fuses multiply-adds, the
                // kernels may not; equal to float rounding.
                for (Eigen::Index i = 0; i < eigen.size(); ++i) {
                    EXPECT_NEAR(avx.data()[i], eigen.data()[i],
                                kAbsTol + kRelTol * std::abs(eigen.data()[i]))
                        << what << " entry " << i << ", " << where;
                }
#else
                EXPECT_EQ(std::memcmp(eigen.data(), avx.data(), sizeof(float) * eigen.size()), 0)
                    << what << ", " << where;
#endif
            };
            for (int k = 1; k <= K; ++k) {
                expect_same(batches[0].activations[k], batches[1].activations[k],
                            "activations " + std::to_string(k));
            }
            for (int k = 1; k < K; ++k) {
                expect_same(batches[0].upstream[k], batches[1].upstream[k],
                            "upstream " + std::to_string(k));
            }
            expect_same(batches[0].input_gradient, batches[1].input_gradient, "input gradient");
            // The masks let some gradients through and stop others.
            const Eigen::MatrixXf& mask_source = batches[0].activations[1];
            const Eigen::Index active = (mask_source.array() > 0.0f).count();
            EXPECT_GT(active, 0) << where;
            EXPECT_LT(active, mask_source.size()) << where;
        }
    }
}
