// Decoder::forward_lanes, DecoderLanes and DecoderLaneQueue (the evaluation path of the bake and of
// map queries) against Decoder::forward: the same value bit for bit, lane by lane, in the queue's
// order.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "shine/core/cpu_features.hpp"
#include "shine/model/decoder.hpp"
#include "shine/model/decoder_lanes.hpp"

using namespace shine;

namespace {
// Without fused multiply-adds (the default x86-64 build) both paths round the same products and
// sums; a build for a CPU with FMA (SHINE_NATIVE) may fuse them differently in each.
#if defined(__FMA__)
constexpr bool kBitExact = false;
#else
constexpr bool kBitExact = true;
#endif

void expect_same(float lanes, float reference, const std::string& what) {
    if (kBitExact && !std::isnan(reference)) {
        std::uint32_t a, b;
        std::memcpy(&a, &lanes, sizeof a);
        std::memcpy(&b, &reference, sizeof b);
        EXPECT_EQ(a, b) << what << ": " << lanes << " vs " << reference;
    } else if (std::isnan(reference)) {
        EXPECT_TRUE(std::isnan(lanes)) << what;
    } else if (lanes != reference) {  // equal infinities have no finite difference
        EXPECT_NEAR(lanes, reference, 1e-5f + 1e-5f * std::abs(reference)) << what;
    }
}

/// Features of `count` samples, row by row: normal values, with exact zeros and signed zeros mixed
/// in (the ReLU's edge) .
std::vector<float> random_features(int count, int dim, unsigned seed) {
    std::mt19937 rng(seed);
    std::normal_distribution<float> normal(0.0f, 0.7f);
    std::vector<float> features(std::size_t(count) * dim);
    for (std::size_t i = 0; i < features.size(); ++i) {
        features[i] = i % 11 == 3 ? 0.0f : i % 13 == 5 ? -0.0f : normal(rng);
    }
    return features;
}
/// kDecoderLanes samples' features, row by row, in the lanes' layout: feature l of sample s at
/// [l * kDecoderLanes + s].
std::vector<float> interleave(const std::vector<float>& features, int dim) {
    std::vector<float> interleaved(std::size_t(dim) * kDecoderLanes);
    for (int s = 0; s < kDecoderLanes; ++s) {
        for (int l = 0; l < dim; ++l) {
            interleaved[std::size_t(l) * kDecoderLanes + s] = features[std::size_t(s) * dim + l];
        }
    }
    return interleaved;
}

/// Runs `check(config, path)` for each decoder shape, with the lanes' AVX kernels (8 lanes in one
/// register, where the CPU has AVX) switched off (Eigen's fixed-size arrays) and on; `path` names
/// which, for the messages.
template <typename Check>
void for_each_shape_and_lane_path(Check check) {
    for (const bool simd : {false, true}) {
        set_simd_enabled(simd);
        for (const DecoderConfig& config :
             {DecoderConfig{8, {32, 32}, 3}, DecoderConfig{5, {7}, 11},
              DecoderConfig{4, {16, 3, 9}, 2}, DecoderConfig{1, {}, 8}}) {
            check(config, simd ? ", AVX" : ", plain");
        }
    }
    set_simd_enabled(true);
}
}  // namespace

TEST(DecoderLanes, ForwardLanesEqualsForwardForEveryLane) {
    for_each_shape_and_lane_path([](const DecoderConfig& config, const std::string& path) {
        const Decoder decoder(config);
        const int dim = config.input_dim;
        const std::vector<float> features = random_features(kDecoderLanes, dim, 17);
        const std::vector<float> interleaved = interleave(features, dim);
        DecoderWorkspace lanes_ws, ws;
        decoder.prepare(ws);
        float out[kDecoderLanes];
        decoder.forward_lanes(interleaved.data(), out, lanes_ws);
        for (int s = 0; s < kDecoderLanes; ++s) {
            const float reference = decoder.forward(features.data() + std::size_t(s) * dim, ws);
            expect_same(out[s], reference,
                        "input " + std::to_string(dim) + ", lane " + std::to_string(s) + path);
        }
    });
}

TEST(DecoderLanes, InputGradientLanesEqualsInputGradientForEveryLane) {
    // Zeros among the features make hidden units exactly zero (the ReLU mask) and rows with a
    // zero upstream value, which input_gradient() skips.
    for_each_shape_and_lane_path([](const DecoderConfig& config, const std::string& path) {
        const Decoder decoder(config);
        const int dim = config.input_dim;
        for (const unsigned seed : {17u, 18u, 19u}) {
            const std::vector<float> features = random_features(kDecoderLanes, dim, seed);
            const std::vector<float> interleaved = interleave(features, dim);
            DecoderWorkspace lanes_ws, ws;
            decoder.prepare(ws);
            float out[kDecoderLanes];
            std::vector<float> h_lanes(std::size_t(dim) * kDecoderLanes);
            decoder.forward_lanes(interleaved.data(), out, lanes_ws);
            decoder.input_gradient_lanes(lanes_ws, h_lanes.data());
            std::vector<float> h(dim);
            for (int s = 0; s < kDecoderLanes; ++s) {
                decoder.forward(features.data() + std::size_t(s) * dim, ws);
                decoder.input_gradient(ws, h.data());
                for (int l = 0; l < dim; ++l) {
                    expect_same(h_lanes[std::size_t(l) * kDecoderLanes + s], h[l],
                                "input " + std::to_string(dim) + ", lane " + std::to_string(s) +
                                    ", h_" + std::to_string(l) + path);
                }
            }
        }
    });
}

TEST(DecoderLanes, QueueReturnsValuesInOrderAlsoForAPartialGroup) {
    const Decoder decoder(DecoderConfig{8, {32, 32}, 21});
    constexpr int kCount = 3 * kDecoderLanes + 5;  // three full groups and a partial one
    const std::vector<float> features = random_features(kCount, 8, 4);
    DecoderLanes lanes(decoder);
    DecoderWorkspace ws;
    decoder.prepare(ws);
    std::vector<float> values;
    for (int i = 0; i < kCount; ++i) {
        EXPECT_EQ(lanes.size(), i % kDecoderLanes);
        lanes.add(features.data() + std::size_t(i) * 8);
        if (lanes.full()) {
            const float* f = lanes.evaluate();
            values.insert(values.end(), f, f + kDecoderLanes);
            EXPECT_EQ(lanes.size(), 0);
        }
    }
    const int rest = lanes.size();
    ASSERT_EQ(rest, 5);
    const float* f = lanes.evaluate();
    values.insert(values.end(), f, f + rest);
    ASSERT_EQ(values.size(), std::size_t(kCount));
    for (int i = 0; i < kCount; ++i) {
        expect_same(values[i], decoder.forward(features.data() + std::size_t(i) * 8, ws),
                    "sample " + std::to_string(i));
    }
    // An empty queue evaluates nothing and stays empty.
    lanes.evaluate();
    EXPECT_EQ(lanes.size(), 0);
}

TEST(DecoderLaneQueue, HandsEachPayloadBackWithItsValueInOrder) {
    const Decoder decoder(DecoderConfig{8, {32, 32}, 21});
    constexpr int kCount = 2 * kDecoderLanes + 3;  // two full groups and a partial one
    const std::vector<float> features = random_features(kCount, 8, 9);
    DecoderLaneQueue<int> queue(decoder);
    DecoderWorkspace ws;
    decoder.prepare(ws);
    std::vector<int> payloads;
    std::vector<float> values;
    const auto emit = [&](int payload, float f) {
        payloads.push_back(payload);
        values.push_back(f);
    };
    // Payloads in reverse order of the samples, so that a payload swapped for its lane fails.
    for (int i = 0; i < kCount; ++i) {
        queue.add(features.data() + std::size_t(i) * 8, 1000 - i, emit);
        EXPECT_EQ(payloads.size(), std::size_t((i + 1) / kDecoderLanes * kDecoderLanes));
    }
    queue.flush(emit);
    ASSERT_EQ(payloads.size(), std::size_t(kCount));
    for (int i = 0; i < kCount; ++i) {
        EXPECT_EQ(payloads[i], 1000 - i);
        expect_same(values[i], decoder.forward(features.data() + std::size_t(i) * 8, ws),
                    "sample " + std::to_string(i));
    }
    queue.flush(emit);  // an empty queue emits nothing
    EXPECT_EQ(payloads.size(), std::size_t(kCount));
}

TEST(DecoderLanes, NonFiniteFeaturesGiveForwardsValues) {
    const Decoder decoder(DecoderConfig{2, {4}, 6});
    const float inf = std::numeric_limits<float>::infinity();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float samples[kDecoderLanes][2] = {{inf, 0.0f},  {-inf, 1.0f},   {nan, 0.5f},
                                             {0.0f, -inf}, {1e30f, 1e30f}, {-1e30f, 2.0f},
                                             {0.25f, nan}, {-0.0f, -0.0f}};
    float interleaved[2 * kDecoderLanes];
    for (int s = 0; s < kDecoderLanes; ++s) {
        interleaved[s] = samples[s][0];
        interleaved[kDecoderLanes + s] = samples[s][1];
    }
    DecoderWorkspace lanes_ws, ws;
    decoder.prepare(ws);
    float out[kDecoderLanes];
    decoder.forward_lanes(interleaved, out, lanes_ws);
    for (int s = 0; s < kDecoderLanes; ++s) {
        expect_same(out[s], decoder.forward(samples[s], ws), "lane " + std::to_string(s));
    }
}
