// One optimisation step of the neural SDF on rays (paper Eq. (4): L_bce + lambda_e * L_eikonal),
// with Adam on the touched feature rows and on the decoder.
//
// A batch is split into fixed chunks; each chunk draws its rays with its own random stream
// (seeded by seed, iteration and chunk) and computes per-sample gradients in parallel with TBB;
// the chunks' contributions are then summed in chunk order. The result is therefore identical for
// a given seed whatever the number of threads.
#pragma once

#include <cstdint>
#include <vector>

#include "shine/model/neural_sdf.hpp"
#include "shine/optim/adam.hpp"
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
    std::size_t valid_samples = 0;
    std::size_t drawn_samples = 0;
};

class Trainer {
  public:
    Trainer(NeuralSdf& sdf, const TrainerConfig& config, const SamplingConfig& sampling);
    ~Trainer();

    /// Call after the octree grew: sizes the optimiser state and gradient buffers.
    void on_map_grown();

    /// One iteration on rays drawn uniformly from [ray_begin, ray_end) of `rays`.
    TrainStepStats step(const RaySet& rays, std::size_t ray_begin, std::size_t ray_end,
                        std::uint64_t iteration);

    const TrainerConfig& config() const { return config_; }
    void set_feature_learning_rate(float lr) { feature_adam_.set_learning_rate(lr); }
    void set_decoder_learning_rate(float lr) { decoder_adam_.set_learning_rate(lr); }
    std::size_t optimizer_bytes() const {
        return feature_adam_.memory_bytes() + decoder_adam_.memory_bytes() +
               feature_grads_.capacity() * sizeof(float);
    }

  private:
    struct Chunk;

    NeuralSdf& sdf_;
    TrainerConfig config_;
    SamplingConfig sampling_;
    RowAdam feature_adam_;
    RowAdam decoder_adam_;
    std::vector<float> feature_grads_;  ///< dense table, zero outside the rows being updated
    std::vector<std::uint8_t> touched_;
    std::vector<std::int32_t> touched_rows_;
    std::vector<float> decoder_grads_;
    std::vector<Chunk> chunks_;
};

}  // namespace shine
