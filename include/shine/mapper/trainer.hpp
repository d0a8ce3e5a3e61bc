// One optimisation step of the neural SDF on rays (paper Eq. (4): L_bce + lambda_e * L_eikonal),
// with Adam on the touched feature rows and on the decoder.
//
// A batch is split into fixed chunks; each chunk draws its rays with its own random stream
// (seeded by seed, iteration and chunk) and computes per-sample gradients in parallel with TBB;
// the chunks' contributions are then summed in chunk order. The result is therefore identical for
// a given seed whatever the number of threads.
//
// A float16 feature table is trained in mixed precision: the forward and backward passes read the
// float16 map, Adam updates a float32 master copy held by the Trainer, and each updated row is
// rounded back into the map, so the map is always the one that queries, baking and saving use.
#pragma once

#include <cstdint>
#include <vector>

#include "shine/model/neural_sdf.hpp"
#include "shine/optim/adam.hpp"
#include "shine/optim/importance_weights.hpp"
#include "shine/sampling/ray_sampler.hpp"
#include "shine/sampling/ray_set.hpp"

namespace shine {

struct TrainerConfig {
    int batch_size = 4096;        ///< samples per iteration (rays = batch / samples per ray)
    float sigma_m = 0.05f;        ///< sigmoid scale of Eq. (1)
    float eikonal_weight = 0.1f;  ///< lambda_e, on surface samples
    bool train_decoder = true;    ///< false in incremental mode with a pretrained decoder
    AdamConfig feature_adam{};    ///< lr 0.01, betas (0.9, 0.99)
    AdamConfig decoder_adam{};
    std::uint64_t seed = 42;
    int num_chunks = 32;  ///< fixed work split (determinism does not depend on threads)
};

/// Losses of one step, averaged over the valid samples.
struct TrainStepStats {
    double bce = 0.0;
    double eikonal = 0.0;
    double regularization = 0.0;  ///< lambda_r * L_r over the touched rows (incremental mode)
    std::size_t valid_samples = 0;
    std::size_t drawn_samples = 0;
};

class Trainer {
  public:
    Trainer(NeuralSdf& sdf, const TrainerConfig& config, const SamplingConfig& sampling);
    ~Trainer();

    /// Call after the octree grew: sizes the optimiser state and gradient buffers (and the
    /// float32 master copy of a float16 map; new rows start from the map's values).
    void on_map_grown();

    /// One iteration on rays drawn uniformly from [ray_begin, ray_end) of `rays`. With a
    /// `regularizer` (incremental mode) the loss adds its lambda_r * L_r over the feature rows the
    /// batch touched (paper Eq. (5)); without one the step is exactly the batch-mode step.
    TrainStepStats step(const RaySet& rays, std::size_t ray_begin, std::size_t ray_end,
                        std::uint64_t iteration, const ImportanceWeights* regularizer = nullptr);

    /// The importance pass of paper Eq. (4): for every ray of [ray_begin, ray_end) once, draws its
    /// samples (from the stream importance_stream_seed(pass, ray)) and adds, per feature row,
    /// the norms |dL_bce(x_k, l_k)/dtheta_row| of each sample's BCE gradient (per sample, not
    /// averaged; no Eikonal term) to `row_sums`, which is resized to num_corners() rows. Returns
    /// the number of samples that fell inside the map. Changes no parameter. Deterministic for
    /// any thread count.
    std::size_t accumulate_bce_gradient_norms(const RaySet& rays, std::size_t ray_begin,
                                              std::size_t ray_end, std::uint64_t pass,
                                              std::vector<float>& row_sums);
    /// Seed of the random stream the importance pass samples ray `ray` of pass `pass` with.
    std::uint64_t importance_stream_seed(std::uint64_t pass, std::uint64_t ray) const;

    /// The float32 feature values Adam updates: the map's table, or the master copy of a float16
    /// map (whose rows the map holds rounded). Importance anchors are taken from these.
    const float* feature_params() const;

    const TrainerConfig& config() const { return config_; }
    void set_feature_learning_rate(float lr) { feature_adam_.set_learning_rate(lr); }
    void set_decoder_learning_rate(float lr) { decoder_adam_.set_learning_rate(lr); }
    std::size_t optimizer_bytes() const {
        return feature_adam_.memory_bytes() + decoder_adam_.memory_bytes() +
               (feature_grads_.capacity() + master_features_.capacity()) * sizeof(float);
    }

  private:
    struct Chunk;

    float* mutable_feature_params();

    NeuralSdf& sdf_;
    TrainerConfig config_;
    SamplingConfig sampling_;
    RowAdam feature_adam_;
    RowAdam decoder_adam_;
    std::vector<float> feature_grads_;    ///< dense table, zero outside the rows being updated
    std::vector<float> master_features_;  ///< float32 copy of a float16 table (else empty)
    std::vector<std::uint8_t> touched_;
    std::vector<std::int32_t> touched_rows_;
    std::vector<float> decoder_grads_;
    std::vector<Chunk> chunks_;
};

}  // namespace shine
