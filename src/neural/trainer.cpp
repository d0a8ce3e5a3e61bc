#include "shine/mapper/trainer.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "shine/core/error.hpp"
#include "shine/core/random.hpp"
#include "shine/model/sample_gradient.hpp"

namespace shine {
namespace {
constexpr int kMaxSamplesPerRay = 64;
constexpr std::uint64_t kImportanceSalt = 0x3c6ef372fe94f82bull;  ///< importance-pass streams
}  // namespace

/// Per-chunk results: feature-gradient records and the chunk's decoder gradient.
struct Trainer::Chunk {
    // Per valid sample: h = df/dF (feature_dim floats) and, per corner, row and coefficient such
    // that dL/dtheta_row += coefficient * h (see step()).
    std::vector<float> h;
    std::vector<std::int32_t> rows;
    std::vector<float> coefficients;
    std::vector<int> corner_count;
    std::vector<float> decoder_grads;
    double bce = 0.0, eikonal = 0.0;
    std::size_t valid = 0, drawn = 0;
};

Trainer::Trainer(NeuralSdf& sdf, const TrainerConfig& config, const SamplingConfig& sampling)
    : sdf_(sdf),
      config_(config),
      sampling_(sampling),
      feature_adam_(config.feature_adam, sdf.octree.feature_dim()),
      decoder_adam_(config.decoder_adam, static_cast<int>(sdf.decoder.num_params())) {
    if (config.batch_size < sampling.samples_per_ray()) {
        throw ConfigError("batch_size must be at least the samples per ray (" +
                          std::to_string(sampling.samples_per_ray()) + ")");
    }
    if (sampling.samples_per_ray() > kMaxSamplesPerRay || sampling.surface_samples < 0 ||
        sampling.free_samples < 0) {
        throw ConfigError("samples per ray must be between 1 and " +
                          std::to_string(kMaxSamplesPerRay));
    }
    if (!(config.sigma_m > 0.0f)) throw ConfigError("sigma_m must be positive");
    if (sdf.octree.feature_dim() > kMaxFeatureDim) throw ConfigError("feature_dim too large");
    decoder_adam_.resize(1);
    decoder_grads_.assign(sdf.decoder.num_params(), 0.0f);
    chunks_.resize(std::max(1, config.num_chunks));
    on_map_grown();
}

Trainer::~Trainer() = default;

void Trainer::on_map_grown() {
    const std::size_t rows = sdf_.octree.num_corners();
    const std::size_t dim = static_cast<std::size_t>(sdf_.octree.feature_dim());
    feature_adam_.resize(rows);
    feature_grads_.resize(rows * dim, 0.0f);
    touched_.resize(rows, 0);
    const FeatureTable& table = sdf_.octree.features();
    if (table.precision() == FeaturePrecision::kFloat32) {
        std::vector<float>().swap(master_features_);
        return;
    }
    // Rows are only ever appended: existing rows keep their unrounded master values.
    const std::size_t known_rows = master_features_.size() / dim;
    master_features_.resize(rows * dim);
    for (std::size_t row = known_rows; row < rows; ++row) {
        table.get_row(row, master_features_.data() + row * dim);
    }
}

float* Trainer::mutable_feature_params() {
    FeatureTable& table = sdf_.octree.features();
    return table.precision() == FeaturePrecision::kFloat32 ? table.floats()
                                                           : master_features_.data();
}

const float* Trainer::feature_params() const {
    return const_cast<Trainer*>(this)->mutable_feature_params();
}

TrainStepStats Trainer::step(const RaySet& rays, std::size_t ray_begin, std::size_t ray_end,
                             std::uint64_t iteration, const ImportanceWeights* regularizer) {
    TrainStepStats stats;
    if (ray_end <= ray_begin) return stats;
    const int dim = sdf_.octree.feature_dim();
    const int per_ray = sampling_.samples_per_ray();
    const int num_chunks = static_cast<int>(chunks_.size());
    const int rays_per_batch = std::max(1, config_.batch_size / per_ray);
    const SampleLossConfig loss_config{config_.sigma_m, config_.eikonal_weight};
    const bool train_decoder = config_.train_decoder;
    const std::size_t num_params = sdf_.decoder.num_params();

    tbb::parallel_for(0, num_chunks, [&](int c) {
        Chunk& chunk = chunks_[c];
        chunk.h.clear();
        chunk.rows.clear();
        chunk.coefficients.clear();
        chunk.corner_count.clear();
        chunk.decoder_grads.assign(train_decoder ? num_params : 0, 0.0f);
        chunk.bce = chunk.eikonal = 0.0;
        chunk.valid = chunk.drawn = 0;
        const int ray_lo = rays_per_batch * c / num_chunks;
        const int ray_hi = rays_per_batch * (c + 1) / num_chunks;
        Pcg32 rng(stream_seed(config_.seed, iteration, static_cast<std::uint64_t>(c)));
        CellLookup lookup(sdf_.octree);
        DecoderWorkspace ws;
        sdf_.decoder.prepare(ws);
        EncodedPoint encoded;
        SampleGradient gradient;
        RaySample samples[kMaxSamplesPerRay];
        float* decoder_grads = train_decoder ? chunk.decoder_grads.data() : nullptr;
        for (int r = ray_lo; r < ray_hi; ++r) {
            const std::size_t ray = ray_begin + rng.below64(ray_end - ray_begin);
            sample_ray(rays.origin_of_ray(ray), rays.endpoint(ray), rays.normal(ray), sampling_,
                       rng, samples);
            for (int s = 0; s < per_ray; ++s) {
                ++chunk.drawn;
                if (!sample_loss_gradient(sdf_, lookup, ws, samples[s], loss_config, encoded,
                                          gradient, decoder_grads)) {
                    continue;
                }
                ++chunk.valid;
                chunk.bce += gradient.bce;
                chunk.eikonal += gradient.eikonal;
                chunk.rows.insert(chunk.rows.end(), encoded.rows,
                                  encoded.rows + encoded.num_corners);
                chunk.coefficients.insert(chunk.coefficients.end(), gradient.coefficients,
                                          gradient.coefficients + encoded.num_corners);
                chunk.h.insert(chunk.h.end(), gradient.h, gradient.h + dim);
                chunk.corner_count.push_back(encoded.num_corners);
            }
        }
    });

    // Reduce in chunk order: the sums do not depend on which thread ran which chunk.
    for (const Chunk& chunk : chunks_) {
        stats.valid_samples += chunk.valid;
        stats.drawn_samples += chunk.drawn;
        stats.bce += chunk.bce;
        stats.eikonal += chunk.eikonal;
    }
    if (stats.valid_samples == 0) return stats;
    const float inv_n = 1.0f / static_cast<float>(stats.valid_samples);
    stats.bce *= inv_n;
    stats.eikonal *= inv_n;

    touched_rows_.clear();
    for (const Chunk& chunk : chunks_) {
        std::size_t corner = 0;
        for (std::size_t s = 0; s < chunk.corner_count.size(); ++s) {
            const float* h = chunk.h.data() + s * dim;
            for (int k = 0; k < chunk.corner_count[s]; ++k, ++corner) {
                const std::int32_t row = chunk.rows[corner];
                const float coefficient = chunk.coefficients[corner] * inv_n;
                float* grad = feature_grads_.data() + std::size_t(row) * dim;
                for (int l = 0; l < dim; ++l) grad[l] += coefficient * h[l];
                if (!touched_[row]) {
                    touched_[row] = 1;
                    touched_rows_.push_back(row);
                }
            }
        }
    }
    if (regularizer) {
        // Eq. (5): the regulariser acts on the rows this iteration used (the set A of Eq. (3)).
        stats.regularization = regularizer->add_gradient(mutable_feature_params(),
                                                         feature_grads_.data(), touched_rows_);
    }
    feature_adam_.step_rows(mutable_feature_params(), feature_grads_.data(), touched_rows_);
    FeatureTable& table = sdf_.octree.features();
    if (table.precision() == FeaturePrecision::kFloat16) {
        // Mixed precision: Adam stepped the float32 master copy; the map holds its rounding.
        for (const std::int32_t row : touched_rows_) {
            table.set_row(std::size_t(row), master_features_.data() + std::size_t(row) * dim);
        }
    }
    for (const std::int32_t row : touched_rows_) {
        std::fill_n(feature_grads_.data() + std::size_t(row) * dim, dim, 0.0f);
        touched_[row] = 0;
    }

    if (train_decoder) {
        std::fill(decoder_grads_.begin(), decoder_grads_.end(), 0.0f);
        for (const Chunk& chunk : chunks_) {
            for (std::size_t i = 0; i < num_params; ++i)
                decoder_grads_[i] += chunk.decoder_grads[i];
        }
        for (float& g : decoder_grads_) g *= inv_n;
        decoder_adam_.step_all(sdf_.decoder.params().data(), decoder_grads_.data());
    }
    return stats;
}

std::uint64_t Trainer::importance_stream_seed(std::uint64_t pass, std::uint64_t ray) const {
    return stream_seed(config_.seed ^ kImportanceSalt, pass, ray);
}

std::size_t Trainer::accumulate_bce_gradient_norms(const RaySet& rays, std::size_t ray_begin,
                                                   std::size_t ray_end, std::uint64_t pass,
                                                   std::vector<float>& row_sums) {
    row_sums.resize(sdf_.octree.num_corners(), 0.0f);
    std::size_t valid_samples = 0;
    if (ray_end <= ray_begin) return valid_samples;
    const int dim = sdf_.octree.feature_dim();
    const int per_ray = sampling_.samples_per_ray();
    const int num_chunks = static_cast<int>(chunks_.size());
    // BCE only: with no Eikonal weight, coefficients[k] = w_k * dL_bce/df, so the sample's
    // gradient on corner k is coefficients[k] * h and its norm |coefficients[k]| * |h|.
    const SampleLossConfig bce_only{config_.sigma_m, 0.0f};
    // Blocks of rays bound the per-chunk records; each ray has its own stream, so the samples do
    // not depend on the split, and the sums are reduced in ray order within each block.
    constexpr std::size_t kBlockRays = 16384;
    for (std::size_t block = ray_begin; block < ray_end; block += kBlockRays) {
        const std::size_t block_rays = std::min(kBlockRays, ray_end - block);
        tbb::parallel_for(0, num_chunks, [&](int c) {
            Chunk& chunk = chunks_[c];
            chunk.rows.clear();
            chunk.coefficients.clear();
            chunk.valid = 0;
            const std::size_t lo = block + block_rays * c / num_chunks;
            const std::size_t hi = block + block_rays * (c + 1) / num_chunks;
            CellLookup lookup(sdf_.octree);
            DecoderWorkspace ws;
            sdf_.decoder.prepare(ws);
            EncodedPoint encoded;
            SampleGradient gradient;
            RaySample samples[kMaxSamplesPerRay];
            for (std::size_t ray = lo; ray < hi; ++ray) {
                Pcg32 rng(importance_stream_seed(pass, ray));
                sample_ray(rays.origin_of_ray(ray), rays.endpoint(ray), rays.normal(ray), sampling_,
                           rng, samples);
                for (int s = 0; s < per_ray; ++s) {
                    if (!sample_loss_gradient(sdf_, lookup, ws, samples[s], bce_only, encoded,
                                              gradient, nullptr)) {
                        continue;
                    }
                    ++chunk.valid;
                    float h_sq = 0.0f;
                    for (int l = 0; l < dim; ++l) h_sq += gradient.h[l] * gradient.h[l];
                    const float h_norm = std::sqrt(h_sq);
                    for (int k = 0; k < encoded.num_corners; ++k) {
                        chunk.rows.push_back(encoded.rows[k]);
                        chunk.coefficients.push_back(std::abs(gradient.coefficients[k]) * h_norm);
                    }
                }
            }
        });
        for (const Chunk& chunk : chunks_) {
            valid_samples += chunk.valid;
            for (std::size_t i = 0; i < chunk.rows.size(); ++i) {
                row_sums[chunk.rows[i]] += chunk.coefficients[i];
            }
        }
    }
    return valid_samples;
}

}  // namespace shine
