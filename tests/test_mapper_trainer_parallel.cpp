// The parallel training step against its serial reference: Trainer::step and the importance
// pass give bit-identical features, decoder weights and importance sums for 1 and 2 threads
// (float32 and float16 maps, decoder trained or frozen, with the regulariser), the vectorised
// Adam rows equal the scalar adam_update(), the row partitions own whole cache lines, and the
// stage profile's medians and totals.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <random>

#include "shine/mapper/stage_profile.hpp"
#include "shine/mapper/trainer.hpp"
#include "shine/optim/adam.hpp"
#include "shine/optim/importance_weights.hpp"
#include "shine/sampling/ray_set.hpp"
#include "shine/sampling/surface_normals.hpp"

using namespace shine;

namespace {
/// A 16-beam sweep over ground with a wall at x = 6 m, mapped at 0.2 m with 3 levels.
struct SweepScene {
    NeuralSdf sdf;
    RaySet rays;

    explicit SweepScene(FeaturePrecision precision)
        : sdf(octree_config(precision), DecoderConfig{8, {32, 32}, 5}) {
        const Eigen::Vector3f origin(0.0f, 0.0f, 1.5f);
        std::vector<Eigen::Vector3f> endpoints;
        for (int beam = 0; beam < 16; ++beam) {
            const float elevation = (-30.0f + 28.0f * beam / 15.0f) * float(M_PI) / 180.0f;
            for (int a = 0; a < 360; ++a) {
                const float azimuth = 2.0f * float(M_PI) * a / 360.0f;
                const Eigen::Vector3f d(std::cos(elevation) * std::cos(azimuth),
                                        std::cos(elevation) * std::sin(azimuth),
                                        std::sin(elevation));
                float t = 20.0f;
                if (d.z() < 0.0f) t = std::min(t, 1.5f / -d.z());
                if (d.x() > 0.0f) t = std::min(t, 6.0f / d.x());
                if (t < 20.0f) endpoints.push_back(origin + t * d);
            }
        }
        rays.add_scan(origin, endpoints);
        sdf.octree.allocate_cells(endpoints);
        rays.set_normals(estimate_ray_normals(rays, NormalConfig{}));
    }
    static FeatureOctreeConfig octree_config(FeaturePrecision precision) {
        FeatureOctreeConfig c;
        c.feature_precision = precision;
        return c;
    }
};

struct TrainResult {
    std::vector<float> features;
    std::vector<float> decoder;
    std::vector<float> importance_sums;
    double last_bce = 0.0;
    double last_regularization = 0.0;
};

TrainResult train(int threads, FeaturePrecision precision, bool train_decoder, bool regularize) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    SweepScene scene(precision);
    TrainerConfig config;
    config.batch_size = 2048;
    config.train_decoder = train_decoder;
    Trainer trainer(scene.sdf, config, SamplingConfig{});
    ImportanceWeights importance(ImportanceConfig{3.0f, 1.0f}, scene.sdf.octree.feature_dim());
    importance.resize(scene.sdf.octree.num_corners());
    TrainResult result;
    if (regularize) {
        trainer.enable_anchors();
        trainer.begin_scan();
    }
    for (std::uint64_t it = 0; it < 12; ++it) {
        if (regularize && it == 6) {
            // Half-way: importance from a subsampled pass; a new scan, so anchors at the current
            // features.
            RowGradientNormSums sums;
            const std::size_t n = trainer.accumulate_bce_gradient_norms(
                scene.rays, 0, scene.rays.num_rays(), 0, sums, 3);
            importance.update_importance_rows(sums.rows, sums.sums, 1.0f / static_cast<float>(n));
            trainer.begin_scan();
            result.importance_sums.assign(scene.sdf.octree.num_corners(), 0.0f);
            for (std::size_t i = 0; i < sums.rows.size(); ++i) {
                result.importance_sums[sums.rows[i]] = sums.sums[i];
            }
        }
        const TrainStepStats stats = trainer.step(scene.rays, 0, scene.rays.num_rays(), it,
                                                  regularize ? &importance : nullptr);
        result.last_bce = stats.bce;
        result.last_regularization = stats.regularization;
    }
    result.features = scene.sdf.octree.features().to_floats();
    result.decoder = scene.sdf.decoder.params();
    return result;
}
}  // namespace

TEST(TrainerParallel, SameResultForOneAndTwoThreads) {
    struct Case {
        FeaturePrecision precision;
        bool train_decoder, regularize;
    };
    for (const Case& c : {Case{FeaturePrecision::kFloat32, true, false},
                          Case{FeaturePrecision::kFloat32, false, true},
                          Case{FeaturePrecision::kFloat16, true, true}}) {
        const TrainResult serial = train(1, c.precision, c.train_decoder, c.regularize);
        const TrainResult parallel = train(2, c.precision, c.train_decoder, c.regularize);
        EXPECT_EQ(serial.features, parallel.features);
        EXPECT_EQ(serial.decoder, parallel.decoder);
        EXPECT_EQ(serial.importance_sums, parallel.importance_sums);
        EXPECT_EQ(serial.last_bce, parallel.last_bce);
        EXPECT_EQ(serial.last_regularization, parallel.last_regularization);
        EXPECT_GT(serial.last_bce, 0.0);
        if (c.regularize) {
            EXPECT_GT(serial.last_regularization, 0.0);
        }
    }
}

TEST(TrainerParallel, RowPartitionsKeepCacheLinesTogetherAndShareTheRowsEvenly) {
    // The reduction's partitions own whole 64-byte lines of per-row data, so that two threads
    // never write the same line: 16 local indices (int32), 4 float16 rows of 8 features.
    constexpr int kRows = Trainer::kRowPartitions * Trainer::kRowsPerPartitionBlock * 8;
    std::vector<int> rows_per_partition(Trainer::kRowPartitions, 0);
    for (std::int32_t row = 0; row < kRows; ++row) {
        const int p = Trainer::partition_of_row(row);
        ASSERT_GE(p, 0);
        ASSERT_LT(p, Trainer::kRowPartitions);
        ++rows_per_partition[p];
        EXPECT_EQ(p, Trainer::partition_of_row(row / 16 * 16)) << row;
        EXPECT_EQ(p, Trainer::partition_of_row(row / 4 * 4)) << row;
    }
    for (const int n : rows_per_partition) EXPECT_EQ(n, kRows / Trainer::kRowPartitions);
    // Neighbouring blocks go to different partitions: rows touched together spread over both
    // threads.
    EXPECT_NE(Trainer::partition_of_row(0),
              Trainer::partition_of_row(Trainer::kRowsPerPartitionBlock));
}

TEST(TrainerParallel, TrainingLowersTheLoss) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
    SweepScene scene(FeaturePrecision::kFloat32);
    TrainerConfig config;
    Trainer trainer(scene.sdf, config, SamplingConfig{});
    const double first = trainer.step(scene.rays, 0, scene.rays.num_rays(), 0).bce;
    double last = first;
    for (std::uint64_t it = 1; it < 150; ++it) {
        last = trainer.step(scene.rays, 0, scene.rays.num_rays(), it).bce;
    }
    EXPECT_LT(last, 0.8 * first);
    EXPECT_GT(trainer.seconds().train, 0.0);
    EXPECT_GT(trainer.seconds().sample, 0.0);
}

TEST(Adam, VectorisedRowsAndTheDenseStepEqualTheScalarUpdate) {
    // adam_update_row() (SSE) on rows visited in random order, as the trainer does, and
    // DenseAdam::step() on the whole table, against adam_update() one parameter at a time.
    constexpr int kDim = 8;
    constexpr std::size_t kRows = 50;
    std::mt19937 rng(4);
    std::normal_distribution<float> normal(0.0f, 1.0f);
    std::vector<float> params(kRows * kDim), grads(kRows * kDim);
    for (float& p : params) p = normal(rng);
    std::vector<float> row_params = params, dense_params = params, dense_reference = params;
    std::vector<float> m(kRows * kDim, 0.0f), v(kRows * kDim, 0.0f);
    std::vector<float> row_m = m, row_v = v, dense_m = m, dense_v = v;
    std::vector<std::uint32_t> steps(kRows, 0);
    const AdamConfig config;
    AdamSchedule schedule(config);
    DenseAdam dense(config, static_cast<int>(kRows * kDim));
    for (int step = 0; step < 5; ++step) {
        for (float& g : grads) g = normal(rng);
        std::vector<std::int32_t> rows;
        for (std::size_t r = 0; r < kRows; ++r) {
            if ((r + step) % 3) rows.push_back(std::int32_t(r));
        }
        std::shuffle(rows.begin(), rows.end(), rng);
        for (const std::int32_t r : rows) {
            const AdamBiasCorrection bias(config, ++steps[r]);
            for (int l = 0; l < kDim; ++l) {
                const std::size_t i = std::size_t(r) * kDim + l;
                adam_update(params[i], m[i], v[i], grads[i], config, bias);
            }
            schedule.reserve_steps(steps[r]);
            const std::size_t base = std::size_t(r) * kDim;
            adam_update_row(row_params.data() + base, grads.data() + base, row_m.data() + base,
                            row_v.data() + base, kDim, config, schedule.reserved_bias(steps[r]));
        }
        const AdamBiasCorrection dense_bias(config, static_cast<std::uint32_t>(step + 1));
        for (std::size_t i = 0; i < dense_reference.size(); ++i) {
            adam_update(dense_reference[i], dense_m[i], dense_v[i], grads[i], config, dense_bias);
        }
        dense.step(dense_params.data(), grads.data());
    }
    EXPECT_EQ(row_params, params);
    EXPECT_EQ(row_m, m);
    EXPECT_EQ(row_v, v);
    EXPECT_EQ(dense.steps(), 5u);
    EXPECT_EQ(dense_params, dense_reference);
}

TEST(StageProfile, MediansTotalsAndTable) {
    StageProfile profile;
    profile.threads = 2;
    for (double train : {0.3, 0.1, 0.2}) {
        StageSeconds frame;
        frame[Stage::kTrain] = train;
        frame[Stage::kNormals] = 0.05;
        profile.frames.push_back(frame);
    }
    profile.run[Stage::kBake] = 1.5;
    EXPECT_DOUBLE_EQ(profile.frame_medians()[Stage::kTrain], 0.2);
    EXPECT_DOUBLE_EQ(profile.frame_medians()[Stage::kBake], 0.0);
    EXPECT_DOUBLE_EQ(profile.median_frame_seconds(), 0.25);
    EXPECT_NEAR(profile.totals()[Stage::kTrain], 0.6, 1e-12);
    EXPECT_DOUBLE_EQ(profile.totals()[Stage::kBake], 1.5);
    const std::string table = profile.format_table();
    for (int i = 0; i < kNumStages; ++i) {
        EXPECT_NE(table.find(stage_name(static_cast<Stage>(i))), std::string::npos) << table;
    }
    EXPECT_NE(table.find("2 threads"), std::string::npos) << table;
}

TEST(Adam, RowOfAnyLengthEqualsTheScalarUpdate) {
    // Lengths that use the SSE loop (4 at a time) and the scalar tail.
    std::mt19937 rng(8);
    std::normal_distribution<float> normal(0.0f, 1.0f);
    const AdamConfig config;
    for (const int dim : {1, 4, 7, 8, 13, 16, 29}) {
        std::vector<float> params(dim), m(dim, 0.0f), v(dim, 0.0f), grads(dim);
        for (float& p : params) p = normal(rng);
        std::vector<float> ref_params = params, ref_m = m, ref_v = v;
        for (std::uint32_t step = 1; step <= 4; ++step) {
            for (float& g : grads) g = normal(rng);
            const AdamBiasCorrection bias(config, step);
            for (int i = 0; i < dim; ++i) {
                adam_update(ref_params[i], ref_m[i], ref_v[i], grads[i], config, bias);
            }
            adam_update_row(params.data(), grads.data(), m.data(), v.data(), dim, config, bias);
        }
        EXPECT_EQ(params, ref_params) << "dim " << dim;
        EXPECT_EQ(m, ref_m) << "dim " << dim;
        EXPECT_EQ(v, ref_v) << "dim " << dim;
    }
}
