// Micro-benchmarks of the kernels a training step and a bake spend their time in: corner lookup
// and trilinear encoding, the decoder (per sample and batched), the batched loss gradient, the
// sparse Adam step, ray sampling, one full Trainer step (1 and 2 threads) and the bake; and the
// endpoint normals of incremental mode (the k-d tree and the whole estimate, 1 and 2 threads).
// Scene: a 40 m x 40 m ground patch with a wall, scanned by one simulated 32-beam sweep, mapped
// at 0.2 m with the default three levels; for the normals, ten such sweeps from sensors 1 m
// apart. See docs/performance.md for how the numbers are used.
#include <benchmark/benchmark.h>
#include <tbb/global_control.h>

#include <cmath>
#include <memory>
#include <random>
#include <vector>

#include "shine/bake/level_set_bake.hpp"
#include "shine/core/cpu_features.hpp"
#include "shine/mapper/trainer.hpp"
#include "shine/model/batch_gradient.hpp"
#include "shine/model/batched_decoder.hpp"
#include "shine/model/feature_encoding.hpp"
#include "shine/model/neural_sdf.hpp"
#include "shine/model/sample_gradient.hpp"
#include "shine/optim/adam.hpp"
#include "shine/sampling/point_kdtree.hpp"
#include "shine/sampling/ray_sampler.hpp"
#include "shine/sampling/ray_set.hpp"
#include "shine/sampling/surface_normals.hpp"

namespace {
using namespace shine;

/// Endpoints of one 32-beam sweep (900 azimuths, 40 m range) of a sensor at `origin` over the
/// ground plane z = 0 and a wall at x = 12 m.
std::vector<Eigen::Vector3f> sweep(const Eigen::Vector3f& origin) {
    std::vector<Eigen::Vector3f> endpoints;
    for (int beam = 0; beam < 32; ++beam) {
        const float elevation = (-25.0f + 27.0f * beam / 31.0f) * float(M_PI) / 180.0f;
        for (int a = 0; a < 900; ++a) {
            const float azimuth = 2.0f * float(M_PI) * a / 900.0f;
            const Eigen::Vector3f d(std::cos(elevation) * std::cos(azimuth),
                                    std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
            float t = 40.0f;
            if (d.z() < 0.0f) t = std::min(t, origin.z() / -d.z());
            if (d.x() > 0.0f) t = std::min(t, (12.0f - origin.x()) / d.x());
            if (t < 40.0f) endpoints.push_back(origin + t * d);
        }
    }
    return endpoints;
}

/// One sweep of a sensor 1.7 m above a ground plane with a wall at x = 12 m, mapped at 0.2 m.
struct Scene {
    NeuralSdf sdf;
    RaySet rays;
    std::vector<RaySample> samples;  ///< 6 samples of each of 4096 rays

    explicit Scene(FeaturePrecision precision = FeaturePrecision::kFloat32)
        : sdf(octree_config(precision), DecoderConfig{}) {
        const Eigen::Vector3f origin(0.0f, 0.0f, 1.7f);
        const std::vector<Eigen::Vector3f> endpoints = sweep(origin);
        rays.add_scan(origin, endpoints);
        sdf.octree.allocate_cells(endpoints);
        rays.set_normals(estimate_ray_normals(rays, NormalConfig{}));
        Pcg32 rng(7);
        SamplingConfig sampling;
        RaySample out[6];
        for (int i = 0; i < 4096; ++i) {
            const std::size_t ray = rng.below64(rays.num_rays());
            sample_ray(rays.origin_of_ray(ray), rays.endpoint(ray), rays.normal(ray), sampling, rng,
                       out);
            samples.insert(samples.end(), out, out + 6);
        }
    }

    static FeatureOctreeConfig octree_config(FeaturePrecision precision) {
        FeatureOctreeConfig config;
        config.feature_precision = precision;
        return config;
    }
};

Scene& scene() {
    static Scene instance;
    return instance;
}

/// The same sweep with a float16 feature table (the maps' default).
Scene& scene_float16() {
    static Scene instance(FeaturePrecision::kFloat16);
    return instance;
}

void BM_EncodeAndGather(benchmark::State& state) {
    const Scene& s = scene();
    CellLookup lookup(s.sdf.octree);
    EncodedPoint encoded;
    float feature[kMaxFeatureDim];
    const bool with_gradients = state.range(0) != 0;
    for (auto _ : state) {
        for (const RaySample& sample : s.samples) {
            encode_point(lookup, s.sdf.octree, sample.point_map, with_gradients, encoded);
            gather_feature(encoded, s.sdf.octree.features().data(), 8, feature);
            benchmark::DoNotOptimize(feature[0]);
        }
    }
    state.SetItemsProcessed(state.iterations() * s.samples.size());
}
BENCHMARK(BM_EncodeAndGather)->Arg(0)->Arg(1)->ArgName("with_gradients");

void BM_DecoderPerSample(benchmark::State& state) {
    const Decoder decoder{DecoderConfig{}};
    DecoderWorkspace ws;
    decoder.prepare(ws);
    std::vector<float> features(8 * 256);
    std::mt19937 rng(3);
    std::normal_distribution<float> normal(0.0f, 0.3f);
    for (float& f : features) f = normal(rng);
    std::vector<float> grads(decoder.num_params(), 0.0f);
    const bool with_params = state.range(0) != 0;
    float h[8];
    for (auto _ : state) {
        for (int b = 0; b < 256; ++b) {
            benchmark::DoNotOptimize(decoder.forward(features.data() + 8 * b, ws));
            decoder.input_gradient(ws, h);
            if (with_params) {
                decoder.accumulate_param_gradient(ws, 0.1f, grads.data());
                decoder.accumulate_input_gradient_param_gradient(ws, h, grads.data());
            }
        }
        benchmark::DoNotOptimize(h[0]);
    }
    state.SetItemsProcessed(state.iterations() * 256);
}
BENCHMARK(BM_DecoderPerSample)->Arg(0)->Arg(1)->ArgName("param_gradients");

void BM_DecoderBatched(benchmark::State& state) {
    const Decoder decoder{DecoderConfig{}};
    DecoderBatch batch;
    prepare_batch(decoder, 256, batch);
    std::mt19937 rng(3);
    std::normal_distribution<float> normal(0.0f, 0.3f);
    for (Eigen::Index i = 0; i < batch.features().size(); ++i)
        batch.features().data()[i] = normal(rng);
    const Eigen::RowVectorXf grad_output = Eigen::RowVectorXf::Constant(256, 0.1f);
    std::vector<float> grads(decoder.num_params(), 0.0f);
    const bool with_params = state.range(0) != 0;
    for (auto _ : state) {
        forward_batch(decoder, batch);
        input_gradient_batch(decoder, batch);
        if (with_params) {
            const Eigen::MatrixXf grad_h = batch.input_gradient;
            accumulate_param_gradient_batch(decoder, batch, grad_output, &grad_h, grads.data());
        }
        benchmark::DoNotOptimize(batch.input_gradient.data());
    }
    state.SetItemsProcessed(state.iterations() * 256);
}
BENCHMARK(BM_DecoderBatched)->Arg(0)->Arg(1)->ArgName("param_gradients");

void BM_SampleLossGradient(benchmark::State& state) {
    const Scene& s = scene();
    CellLookup lookup(s.sdf.octree);
    DecoderWorkspace ws;
    s.sdf.decoder.prepare(ws);
    EncodedPoint encoded;
    SampleGradient gradient;
    std::vector<float> grads(s.sdf.decoder.num_params(), 0.0f);
    float* decoder_grads = state.range(0) ? grads.data() : nullptr;
    for (auto _ : state) {
        for (const RaySample& sample : s.samples) {
            sample_loss_gradient(s.sdf, lookup, ws, sample, SampleLossConfig{}, encoded, gradient,
                                 decoder_grads);
        }
        benchmark::DoNotOptimize(gradient.h[0]);
    }
    state.SetItemsProcessed(state.iterations() * s.samples.size());
}
BENCHMARK(BM_SampleLossGradient)->Arg(0)->Arg(1)->ArgName("train_decoder");

void BM_BatchLossGradient(benchmark::State& state) {
    const Scene& s = scene();
    CellLookup lookup(s.sdf.octree);
    BatchGradient batch;
    std::vector<float> grads(s.sdf.decoder.num_params(), 0.0f);
    float* decoder_grads = state.range(0) ? grads.data() : nullptr;
    constexpr std::size_t kChunk = 128;  // about a trainer chunk
    for (auto _ : state) {
        for (std::size_t i = 0; i + kChunk <= s.samples.size(); i += kChunk) {
            batch_loss_gradient(s.sdf, lookup, s.samples.data() + i, kChunk, SampleLossConfig{},
                                batch, decoder_grads);
        }
        benchmark::DoNotOptimize(batch.bce_sum);
    }
    state.SetItemsProcessed(state.iterations() * s.samples.size());
}
BENCHMARK(BM_BatchLossGradient)->Arg(0)->Arg(1)->ArgName("train_decoder");

/// batch_loss_gradient() on a float16 map (decoder frozen, as in incremental mode), with the
/// AVX/F16C gather (simd:1, where the CPU has it) and the plain one (simd:0).
void BM_BatchLossGradientFloat16(benchmark::State& state) {
    const Scene& s = scene_float16();
    set_simd_enabled(state.range(0) != 0);
    CellLookup lookup(s.sdf.octree);
    BatchGradient batch;
    constexpr std::size_t kChunk = 128;
    for (auto _ : state) {
        for (std::size_t i = 0; i + kChunk <= s.samples.size(); i += kChunk) {
            batch_loss_gradient(s.sdf, lookup, s.samples.data() + i, kChunk, SampleLossConfig{},
                                batch, nullptr);
        }
        benchmark::DoNotOptimize(batch.bce_sum);
    }
    set_simd_enabled(true);
    state.SetItemsProcessed(state.iterations() * s.samples.size());
}
BENCHMARK(BM_BatchLossGradientFloat16)->Arg(0)->Arg(1)->ArgName("simd");

void BM_AdamStepRows(benchmark::State& state) {
    // The trainer's feature update: adam_update_row() on rows touched in random order.
    constexpr std::size_t kRows = 400000, kTouched = 30000;
    constexpr int kDim = 8;
    std::vector<float> params(kRows * kDim, 0.1f), grads(kRows * kDim, 0.01f);
    std::vector<float> moments(kRows * 2 * kDim, 0.0f);
    std::vector<std::uint32_t> steps(kRows, 0);
    std::vector<std::int32_t> rows;
    std::mt19937 rng(1);
    for (std::size_t i = 0; i < kTouched; ++i) rows.push_back(std::int32_t(rng() % kRows));
    AdamSchedule schedule(AdamConfig{});
    schedule.reserve_steps(1u << 20);
    for (auto _ : state) {
        for (const std::int32_t row : rows) {
            const std::size_t r = std::size_t(row);
            float* m = moments.data() + r * 2 * kDim;
            adam_update_row(params.data() + r * kDim, grads.data() + r * kDim, m, m + kDim, kDim,
                            schedule.config(), schedule.reserved_bias(++steps[r]));
        }
        benchmark::DoNotOptimize(params.data());
    }
    state.SetItemsProcessed(state.iterations() * kTouched);
}
BENCHMARK(BM_AdamStepRows);

void BM_SampleRay(benchmark::State& state) {
    const Scene& s = scene();
    Pcg32 rng(3);
    SamplingConfig sampling;
    RaySample out[6];
    std::size_t ray = 0;
    for (auto _ : state) {
        sample_ray(s.rays.origin_of_ray(ray), s.rays.endpoint(ray), s.rays.normal(ray), sampling,
                   rng, out);
        benchmark::DoNotOptimize(out[0].sdf_label_m);
        if (++ray == s.rays.num_rays()) ray = 0;
    }
    state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_SampleRay);

/// One Trainer step of 4096 samples (incremental mode's: decoder frozen) with 1 or 2 threads.
void BM_TrainerStep(benchmark::State& state) {
    Scene& s = scene();
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(state.range(0)));
    TrainerConfig config;
    config.train_decoder = state.range(1) != 0;
    const Decoder saved_decoder = s.sdf.decoder;
    const std::vector<float> saved_features = s.sdf.octree.features().to_floats();
    Trainer trainer(s.sdf, config, SamplingConfig{});
    std::uint64_t iteration = 0;
    for (auto _ : state) {
        benchmark::DoNotOptimize(trainer.step(s.rays, 0, s.rays.num_rays(), iteration++).bce);
    }
    s.sdf.decoder = saved_decoder;
    std::copy(saved_features.begin(), saved_features.end(), s.sdf.octree.features().floats());
    state.SetItemsProcessed(state.iterations() * config.batch_size);
}
BENCHMARK(BM_TrainerStep)
    ->ArgsProduct({{1, 2}, {0, 1}})
    ->ArgNames({"threads", "train_decoder"})
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

/// Incremental mode's normal window: ten sweeps from sensors 1 m apart along x (about 250 k
/// endpoints); the normals are asked for the last sweep.
struct NormalWindow {
    RaySet rays;
    std::size_t query_begin = 0;

    NormalWindow() {
        for (int s = 9; s >= 0; --s) {
            const Eigen::Vector3f origin(-1.0f * s, 0.1f * s, 1.7f);
            query_begin = rays.num_rays();
            rays.add_scan(origin, sweep(origin));
        }
    }
};

NormalWindow& normal_window() {
    static NormalWindow instance;
    return instance;
}

/// The k-d tree over every endpoint of the window (the build incremental mode pays each frame).
void BM_PointKdTreeBuild(benchmark::State& state) {
    const NormalWindow& w = normal_window();
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(state.range(0)));
    std::vector<IndexedPoint> points;
    for (std::size_t r = 0; r < w.rays.num_rays(); ++r) {
        points.push_back({w.rays.endpoint(r), static_cast<std::uint32_t>(r)});
    }
    for (auto _ : state) {
        const PointKdTree tree(points);
        benchmark::DoNotOptimize(tree.size());
    }
    state.SetItemsProcessed(state.iterations() * points.size());
}
BENCHMARK(BM_PointKdTreeBuild)
    ->Arg(1)
    ->Arg(2)
    ->ArgName("threads")
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

/// The 16 nearest endpoints within 1 m of each endpoint of the last sweep (one thread).
void BM_PointKdTreeNearest(benchmark::State& state) {
    const NormalWindow& w = normal_window();
    std::vector<IndexedPoint> points;
    for (std::size_t r = 0; r < w.rays.num_rays(); ++r) {
        points.push_back({w.rays.endpoint(r), static_cast<std::uint32_t>(r)});
    }
    const PointKdTree tree(points);
    PointNeighbor neighbors[PointKdTree::kMaxNeighbors];
    for (auto _ : state) {
        for (std::size_t r = w.query_begin; r < w.rays.num_rays(); ++r) {
            benchmark::DoNotOptimize(tree.nearest(w.rays.endpoint(r), 16, 1.0f, neighbors));
        }
    }
    state.SetItemsProcessed(state.iterations() * (w.rays.num_rays() - w.query_begin));
}
BENCHMARK(BM_PointKdTreeNearest)->Unit(benchmark::kMillisecond);

/// estimate_ray_normals for the last sweep among the window's endpoints: tree, queries and PCA.
void BM_EstimateRayNormalsWindow(benchmark::State& state) {
    const NormalWindow& w = normal_window();
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                              static_cast<std::size_t>(state.range(0)));
    for (auto _ : state) {
        const std::vector<Eigen::Vector3f> normals =
            estimate_ray_normals(w.rays, NormalConfig{}, w.query_begin, w.rays.num_rays());
        benchmark::DoNotOptimize(normals.data());
    }
    state.SetItemsProcessed(state.iterations() * (w.rays.num_rays() - w.query_begin));
}
BENCHMARK(BM_EstimateRayNormalsWindow)
    ->Arg(1)
    ->Arg(2)
    ->ArgName("threads")
    ->UseRealTime()
    ->Unit(benchmark::kMillisecond);

void BM_Bake(benchmark::State& state) {
    const Scene& s = scene();
    BakeStats stats;
    for (auto _ : state) {
        auto grid = bake_level_set(s.sdf, BakeConfig{}, &stats);
        benchmark::DoNotOptimize(grid.get());
    }
    state.SetItemsProcessed(state.iterations() * stats.evaluated_voxels);
}
BENCHMARK(BM_Bake)->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
