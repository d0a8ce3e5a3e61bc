#include "shine/mapper/trainer.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "shine/core/error.hpp"
#include "shine/core/random.hpp"
#include "shine/core/stopwatch.hpp"
#include "shine/io/binary_stream.hpp"
#include "shine/mapper/partition_records.hpp"
#include "shine/model/batch_gradient.hpp"
#include "shine/sampling/ray_draw.hpp"

namespace shine {
namespace {
constexpr int kMaxSamplesPerRay = 64;
constexpr std::uint64_t kImportanceSalt = 0x3c6ef372fe94f82bull;  ///< importance-pass streams

}  // namespace

/// Per-chunk results: the chunk's samples, their batched gradients, the records of each row
/// partition and the chunk's decoder gradient.
struct Trainer::Chunk {
    std::vector<RaySample> samples;  ///< the chunk's samples of the current step
    BatchGradient batch;
    /// Per row partition, the records of the valid samples' corners, in sample and corner order.
    std::vector<PartitionRecord> records[kRowPartitions];
    std::vector<float> decoder_grads;
    std::size_t valid = 0, drawn = 0;

    /// Sorts the batch's (sample, corner) records into the row partitions.
    void bucket_records() {
        for (auto& r : records) r.clear();
        const std::size_t stride = static_cast<std::size_t>(batch.corner_stride);
        for (std::size_t b = 0; b < batch.num_valid(); ++b) {
            const std::size_t first = b * stride;
            for (int k = 0; k < batch.corners[b]; ++k) {
                const std::int32_t row = batch.rows[first + k];
                records[partition_of_row(row)].push_back(
                    {row, batch.coefficients[first + k], static_cast<std::uint32_t>(b)});
            }
        }
    }
};

/// Per row partition: the rows the step touched, in first-touch order, their gradients (compact,
/// feature_dim floats per touched row, at the front of a buffer that may be longer) and the
/// regulariser's value.
struct Trainer::Partition {
    std::vector<std::int32_t> touched_rows;
    std::vector<float> grads;
    double regularization = 0.0;
};

namespace {
/// Throws ConfigError unless `sampling` draws 1 to kMaxSamplesPerRay samples per ray, none of
/// its counts negative, and a batch of `batch_size` holds at least one ray.
void check_samples_per_ray(const SamplingConfig& sampling, int batch_size) {
    if (batch_size < sampling.samples_per_ray()) {
        throw ConfigError("batch_size must be at least the samples per ray (" +
                          std::to_string(sampling.samples_per_ray()) + ")");
    }
    if (sampling.samples_per_ray() < 1 || sampling.samples_per_ray() > kMaxSamplesPerRay ||
        sampling.surface_samples < 0 || sampling.free_samples < 0) {
        throw ConfigError("samples per ray must be between 1 and " +
                          std::to_string(kMaxSamplesPerRay));
    }
}
}  // namespace

Trainer::Trainer(NeuralSdf& sdf, const TrainerConfig& config, const SamplingConfig& sampling)
    : sdf_(sdf),
      config_(config),
      sampling_(sampling),
      feature_adam_(config.feature_adam),
      decoder_adam_(config.decoder_adam, static_cast<int>(sdf.decoder.num_params())),
      row_state_(sdf.octree.feature_dim(), /*with_anchor=*/false,
                 sdf.octree.feature_precision() == FeaturePrecision::kFloat16) {
    check_samples_per_ray(sampling, config.batch_size);
    if (!(config.sigma_m > 0.0f)) throw ConfigError("sigma_m must be positive");
    if (sdf.octree.feature_dim() > kMaxFeatureDim) throw ConfigError("feature_dim too large");
    decoder_grads_.assign(sdf.decoder.num_params(), 0.0f);
    chunks_.resize(std::max(1, config.num_chunks));
    partitions_.resize(kRowPartitions);
    on_map_grown();
}

Trainer::~Trainer() = default;

void Trainer::set_free_samples_and_batch_size(int free_samples, int batch_size) {
    SamplingConfig sampling = sampling_;
    sampling.free_samples = free_samples;
    check_samples_per_ray(sampling, batch_size);
    sampling_.free_samples = free_samples;
    config_.batch_size = batch_size;
}

void Trainer::on_map_grown() {
    const std::size_t rows = sdf_.octree.num_corners();
    row_state_.resize(rows);
    local_index_.resize(rows, -1);
}

void Trainer::enable_anchors() {
    if (row_state_.has_anchor()) return;
    if (steps_taken_ > 0) throw ConfigError("Trainer::enable_anchors() after training started");
    row_state_ =
        FeatureRowState(sdf_.octree.feature_dim(), /*with_anchor=*/true, row_state_.has_master());
    row_state_.resize(sdf_.octree.num_corners());
}

std::size_t Trainer::release_inactive_state(std::uint32_t keep_scans) {
    if (keep_scans == 0 || scan_ < keep_scans) return 0;
    return row_state_.release_unused_pages(scan_ - keep_scans + 1);
}

void Trainer::save_state(BinaryWriter& out) const {
    out.tag("trainer");
    out.value<std::uint32_t>(steps_taken_);
    out.value<std::uint32_t>(scan_);
    decoder_adam_.save(out);
    row_state_.save(out);
}

void Trainer::load_state(BinaryReader& in) {
    in.expect_tag("trainer");
    const auto steps_taken = in.value<std::uint32_t>("trainer step count");
    const auto scan = in.value<std::uint32_t>("trainer scan count");
    decoder_adam_.load(in);
    row_state_.load(in);
    steps_taken_ = steps_taken;
    scan_ = scan;
    local_index_ = TrivialArray<std::int32_t>();
    local_index_.resize(sdf_.octree.num_corners(), -1);
}

TrainStepStats Trainer::step(const RaySet& rays, std::size_t ray_begin, std::size_t ray_end,
                             std::uint64_t iteration, const ImportanceWeights* regularizer,
                             const RayFocus& focus) {
    TrainStepStats stats;
    if (ray_end <= ray_begin) return stats;
    const int dim = sdf_.octree.feature_dim();
    const int per_ray = sampling_.samples_per_ray();
    const int num_chunks = static_cast<int>(chunks_.size());
    const int rays_per_batch = std::max(1, config_.batch_size / per_ray);
    const SampleLossConfig loss_config{config_.sigma_m, config_.eikonal_weight};
    const bool train_decoder = config_.train_decoder;
    const std::size_t num_params = sdf_.decoder.num_params();

    // Phase 1: each chunk draws its rays and their samples from its own stream.
    auto start = std::chrono::steady_clock::now();
    const bool focused = focus.share > 0.0f && focus.begin > ray_begin && focus.begin < ray_end;
    // A ray is focused when a 24-bit draw falls below the share (exact for multiples of 2^-24).
    const auto focus_threshold =
        static_cast<std::uint64_t>(std::ldexp(static_cast<double>(focus.share), 24));
    // Rays grouped by voxel are drawn from a mixture of voxels and points (ray_draw.hpp).
    const RayDrawer whole(rays, ray_begin, ray_end, sampling_.every_point_share);
    const RayDrawer focused_part(rays, focused ? focus.begin : ray_begin, ray_end,
                                 sampling_.every_point_share);
    if (whole.empty()) return stats;
    tbb::parallel_for(0, num_chunks, [&](int c) {
        Chunk& chunk = chunks_[c];
        const int ray_lo = rays_per_batch * c / num_chunks;
        const int ray_hi = rays_per_batch * (c + 1) / num_chunks;
        chunk.samples.resize(std::size_t(ray_hi - ray_lo) * per_ray);
        Pcg32 rng(stream_seed(config_.seed, iteration, static_cast<std::uint64_t>(c)));
        for (int r = ray_lo; r < ray_hi; ++r) {
            const bool in_focus = focused && rng.below64(std::uint64_t{1} << 24) < focus_threshold;
            const std::size_t ray = (in_focus ? focused_part : whole).draw(rng);
            sample_ray(rays.origin_of_ray(ray), rays.endpoint(ray), rays.normal(ray), sampling_,
                       rng, chunk.samples.data() + std::size_t(r - ray_lo) * per_ray);
        }
    });
    seconds_.sample += seconds_since(start);
    start = std::chrono::steady_clock::now();

    // Phase 2: per-chunk losses and gradients, records sorted by row partition.
    tbb::parallel_for(0, num_chunks, [&](int c) {
        Chunk& chunk = chunks_[c];
        chunk.decoder_grads.assign(train_decoder ? num_params : 0, 0.0f);
        CellLookup lookup(sdf_.octree);
        batch_loss_gradient(sdf_, lookup, chunk.samples.data(), chunk.samples.size(), loss_config,
                            chunk.batch, train_decoder ? chunk.decoder_grads.data() : nullptr);
        chunk.drawn = chunk.samples.size();
        chunk.valid = chunk.batch.num_valid();
        chunk.bucket_records();
    });

    // Reduce in chunk order: the sums do not depend on which thread ran which chunk.
    for (const Chunk& chunk : chunks_) {
        stats.valid_samples += chunk.valid;
        stats.drawn_samples += chunk.drawn;
        stats.bce += chunk.batch.bce_sum;
        stats.eikonal += chunk.batch.eikonal_sum;
    }
    if (stats.valid_samples == 0) {
        seconds_.train += seconds_since(start);
        return stats;
    }
    const float inv_n = 1.0f / static_cast<float>(stats.valid_samples);
    stats.bce *= inv_n;
    stats.eikonal *= inv_n;

    // Phase 3: per row partition, in parallel: sum the feature gradients in chunk order, add the
    // regulariser's gradient (Eq. (5), on the rows this iteration used: the set A of Eq. (3)),
    // step Adam on the touched rows and clear their gradients.
    ++steps_taken_;
    feature_adam_.reserve_steps(steps_taken_);
    FeatureTable& table = sdf_.octree.features();
    const bool half = table.precision() == FeaturePrecision::kFloat16;
    float* table_floats = half ? nullptr : table.floats();
    const Imath::half* table_halves = half ? table.halves() : nullptr;
    const AdamConfig& adam = feature_adam_.config();
    const bool regularize = regularizer != nullptr;
    if (regularize && (!row_state_.has_anchor() || scan_ == 0)) {
        throw ConfigError(
            "Trainer::step() with a regulariser needs enable_anchors() and "
            "begin_scan() first");
    }
    tbb::parallel_for(0, kRowPartitions, [&](int p) {
        Partition& partition = partitions_[p];
        std::vector<std::int32_t>& rows = partition.touched_rows;
        std::vector<float>& grads = partition.grads;
        rows.clear();
        partition.regularization = 0.0;
        // Room for a gradient per record, the most rows the partition can touch; a row's entries
        // are zeroed when it is first met, so the buffer is only ever grown.
        std::size_t num_records = 0;
        for (const Chunk& chunk : chunks_) num_records += chunk.records[p].size();
        if (grads.size() < num_records * dim) grads.resize(num_records * dim);
        if (rows.capacity() < num_records) rows.reserve(num_records);
        for (const Chunk& chunk : chunks_) {
            add_partition_records(chunk.batch, chunk.records[p], dim, inv_n, local_index_.data(),
                                  rows, grads.data());
        }
        // Per touched row: its state block, the regulariser's gradient (Eq. (5), on the rows this
        // iteration used: the set A of Eq. (3)) and the Adam step. Rows are in random order and
        // the loop is bound by cache misses: the blocks of rows a few ahead are requested early.
        // A row's state is looked up once, when it is requested; ring[j % kAhead] keeps its block.
        // 8 rows ahead: more than 4 gained nothing while the partitions shared cache lines, 8
        // gains since, and 12 gain nothing over 8 (docs/performance.md).
        double regularization = 0.0;
        constexpr std::size_t kAhead = 8;
        float* ring[kAhead];
        const auto request = [&](std::size_t j) {
            float* block = row_state_.touch_block(rows[j], scan_);
            const FeatureRowState::Row ahead = row_state_.row_in_block(block);
            __builtin_prefetch(ahead.first_moment, 1);
            __builtin_prefetch(ahead.step, 1);
            if (regularize) {
                __builtin_prefetch(ahead.anchor, 1);  // the block's next cache line
                regularizer->prefetch_row(rows[j]);
            }
            // The map's row, which the step writes (a float16 map: its rounding of the master).
            if (half) {
                __builtin_prefetch(table_halves + std::size_t(rows[j]) * dim, 1);
            } else {
                __builtin_prefetch(table_floats + std::size_t(rows[j]) * dim, 1);
            }
            ring[j % kAhead] = block;
        };
        for (std::size_t j = 0; j < std::min(kAhead, rows.size()); ++j) request(j);
        for (std::size_t i = 0; i < rows.size(); ++i) {
            const std::int32_t row = rows[i];
            const FeatureRowState::Row state = row_state_.row_in_block(ring[i % kAhead]);
            if (i + kAhead < rows.size()) request(i + kAhead);
            float* param;
            if (half) {
                // Mixed precision: Adam steps the float32 master copy, made from the map's value
                // the first time the row is trained; the map holds its rounding.
                param = state.master;
                if (*state.master_valid == 0) {
                    table.get_row(std::size_t(row), param);
                    *state.master_valid = 1;
                }
            } else {
                param = table_floats + std::size_t(row) * dim;
            }
            float* grad = grads.data() + i * dim;
            if (regularize) {
                if (*state.anchor_scan != scan_) {
                    std::copy(param, param + dim, state.anchor);
                    *state.anchor_scan = scan_;
                }
                regularization += regularizer->add_row_gradient(row, param, state.anchor, grad);
            }
            const std::uint32_t row_step = ++*state.step;
            adam_update_row(param, grad, state.first_moment, state.second_moment, dim, adam,
                            feature_adam_.reserved_bias(row_step));
            if (half) table.set_row(std::size_t(row), param);
            local_index_[row] = -1;
        }
        if (regularize) {
            partition.regularization = regularizer->config().regularization_weight * regularization;
        }
    });
    for (const Partition& partition : partitions_) stats.regularization += partition.regularization;

    if (train_decoder) {
        std::fill(decoder_grads_.begin(), decoder_grads_.end(), 0.0f);
        for (const Chunk& chunk : chunks_) {
            for (std::size_t i = 0; i < num_params; ++i)
                decoder_grads_[i] += chunk.decoder_grads[i];
        }
        for (float& g : decoder_grads_) g *= inv_n;
        decoder_adam_.step(sdf_.decoder.params().data(), decoder_grads_.data());
    }
    seconds_.train += seconds_since(start);
    return stats;
}

std::uint64_t Trainer::importance_stream_seed(std::uint64_t pass, std::uint64_t ray) const {
    return stream_seed(config_.seed ^ kImportanceSalt, pass, ray);
}

std::size_t Trainer::accumulate_bce_gradient_norms(const RaySet& rays, std::size_t ray_begin,
                                                   std::size_t ray_end, std::uint64_t pass,
                                                   RowGradientNormSums& row_sums,
                                                   std::size_t ray_stride,
                                                   std::size_t seed_ray_origin) {
    row_sums.rows.clear();
    row_sums.sums.clear();
    std::size_t valid_samples = 0;
    if (ray_end <= ray_begin) return valid_samples;
    if (seed_ray_origin > ray_begin) {
        throw ConfigError("Trainer::accumulate_bce_gradient_norms: the streams' first ray " +
                          std::to_string(seed_ray_origin) + " is after the first ray " +
                          std::to_string(ray_begin));
    }
    for (Partition& partition : partitions_) {
        partition.touched_rows.clear();
        partition.grads.clear();  // here: one sum per touched row
    }
    ray_stride = std::max<std::size_t>(ray_stride, 1);
    const auto start = std::chrono::steady_clock::now();
    const int per_ray = sampling_.samples_per_ray();
    const int num_chunks = static_cast<int>(chunks_.size());
    // BCE only: with no Eikonal weight, coefficients[k] = w_k * dL_bce/df, so the sample's
    // gradient on corner k is coefficients[k] * h and its norm |coefficients[k]| * |h|.
    const SampleLossConfig bce_only{config_.sigma_m, 0.0f};
    // Blocks of rays bound the per-chunk records; each ray has its own stream, so the samples do
    // not depend on the split, and each row partition adds its rows' norms in ray order.
    constexpr std::size_t kBlockRays = 16384;
    const std::size_t num_rays = (ray_end - ray_begin + ray_stride - 1) / ray_stride;
    for (std::size_t block = 0; block < num_rays; block += kBlockRays) {
        const std::size_t block_rays = std::min(kBlockRays, num_rays - block);
        tbb::parallel_for(0, num_chunks, [&](int c) {
            Chunk& chunk = chunks_[c];
            const std::size_t lo = block + block_rays * c / num_chunks;
            const std::size_t hi = block + block_rays * (c + 1) / num_chunks;
            chunk.samples.resize((hi - lo) * per_ray);
            for (std::size_t i = lo; i < hi; ++i) {
                const std::size_t ray = ray_begin + i * ray_stride;
                Pcg32 rng(importance_stream_seed(pass, ray - seed_ray_origin));
                sample_ray(rays.origin_of_ray(ray), rays.endpoint(ray), rays.normal(ray), sampling_,
                           rng, chunk.samples.data() + (i - lo) * per_ray);
            }
            CellLookup lookup(sdf_.octree);
            batch_loss_gradient(sdf_, lookup, chunk.samples.data(), chunk.samples.size(), bce_only,
                                chunk.batch, nullptr);
            BatchGradient& batch = chunk.batch;
            chunk.valid = batch.num_valid();
            // The coefficients become the per-sample gradient norms |coefficient_k| * |h|.
            for (std::size_t b = 0; b < batch.num_valid(); ++b) {
                const float h_norm =
                    Eigen::Map<const Eigen::VectorXf>(batch.h(b), sdf_.octree.feature_dim()).norm();
                float* coefficients = batch.coefficients.data() + b * batch.corner_stride;
                for (int k = 0; k < batch.corners[b]; ++k) {
                    coefficients[k] = std::abs(coefficients[k]) * h_norm;
                }
            }
            chunk.bucket_records();
        });
        for (const Chunk& chunk : chunks_) valid_samples += chunk.valid;
        // Each partition sums its rows' norms in block and chunk order (a compact sum per row).
        tbb::parallel_for(0, kRowPartitions, [&](int p) {
            Partition& partition = partitions_[p];
            for (const Chunk& chunk : chunks_) {
                for (const PartitionRecord& record : chunk.records[p]) {
                    std::int32_t& local = local_index_[record.row];
                    if (local < 0) {
                        local = static_cast<std::int32_t>(partition.touched_rows.size());
                        partition.touched_rows.push_back(record.row);
                        partition.grads.push_back(0.0f);
                    }
                    partition.grads[std::size_t(local)] += record.coefficient;
                }
            }
        });
    }
    for (Partition& partition : partitions_) {
        for (std::size_t i = 0; i < partition.touched_rows.size(); ++i) {
            local_index_[partition.touched_rows[i]] = -1;
        }
        row_sums.rows.insert(row_sums.rows.end(), partition.touched_rows.begin(),
                             partition.touched_rows.end());
        row_sums.sums.insert(row_sums.sums.end(), partition.grads.begin(), partition.grads.end());
    }
    seconds_.importance += seconds_since(start);
    return valid_samples;
}

}  // namespace shine
