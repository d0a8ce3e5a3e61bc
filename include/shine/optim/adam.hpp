// Adam (Kingma & Ba) for the decoder (dense) and the feature table (sparse rows).
//
// Feature rows are updated only when a batch touched them ("lazy" sparse Adam): rows a batch did
// not reach keep their value and moments, so distant parts of the map are not nudged by stale
// momentum. Bias correction uses each row's own step count.
#pragma once

#include <cmath>
#include <cstdint>
#include <vector>

namespace shine {

class BinaryReader;
class BinaryWriter;

struct AdamConfig {
    float learning_rate = 0.01f;
    float beta1 = 0.9f;
    float beta2 = 0.99f;
    float epsilon = 1e-15f;
};

/// Bias corrections 1/(1 - beta^step) of Adam's moments for a 1-based step count.
struct AdamBiasCorrection {
    float inv_first;
    float inv_second;
    AdamBiasCorrection(const AdamConfig& c, std::uint32_t step)
        : inv_first(1.0f / (1.0f - std::pow(c.beta1, static_cast<float>(step)))),
          inv_second(1.0f / (1.0f - std::pow(c.beta2, static_cast<float>(step)))) {}
};

/// One Adam step of a single parameter.
inline void adam_update(float& param, float& m, float& v, float grad, const AdamConfig& c,
                        const AdamBiasCorrection& bias) {
    m = c.beta1 * m + (1.0f - c.beta1) * grad;
    v = c.beta2 * v + (1.0f - c.beta2) * grad * grad;
    param -= c.learning_rate * (m * bias.inv_first) / (std::sqrt(v * bias.inv_second) + c.epsilon);
}

/// adam_update() on `dim` parameters with their moments m and v (bit-identical to it, SIMD).
void adam_update_row(float* param, const float* grad, float* m, float* v, int dim,
                     const AdamConfig& config, const AdamBiasCorrection& bias);

/// Adam's settings and the bias corrections of each step count, computed once per step value
/// (std::pow is costly). The moments live elsewhere: the feature rows' with the rest of a row's
/// state (feature_row_state.hpp), the decoder's in DenseAdam.
class AdamSchedule {
  public:
    AdamSchedule() = default;
    explicit AdamSchedule(const AdamConfig& config) : config_(config) {}

    const AdamConfig& config() const { return config_; }
    void set_learning_rate(float lr) { config_.learning_rate = lr; }
    /// Precomputes the bias corrections up to step `max_step`, so that reserved_bias() of any
    /// step up to it only reads (and may be called concurrently).
    void reserve_steps(std::uint32_t max_step);
    /// The bias corrections of step `step` (1-based), which reserve_steps() must cover.
    const AdamBiasCorrection& reserved_bias(std::uint32_t step) const {
        return bias_by_step_[step - 1];
    }

  private:
    AdamConfig config_;
    std::vector<AdamBiasCorrection> bias_by_step_;  ///< index step-1
};

/// Adam on one dense parameter vector of `dim` floats (the decoder): its moments and step count.
class DenseAdam {
  public:
    DenseAdam() = default;
    DenseAdam(const AdamConfig& config, int dim);

    const AdamConfig& config() const { return config_; }
    void set_learning_rate(float lr) { config_.learning_rate = lr; }
    /// One Adam step of all `dim` parameters with their gradients.
    void step(float* params, const float* grads);
    std::uint32_t steps() const { return step_; }
    std::size_t memory_bytes() const;

    /// The moments and the step count (for a checkpoint); load() replaces them and throws
    /// IoError (via the reader) if the stored vector's size differs from this one's.
    void save(BinaryWriter& out) const;
    void load(BinaryReader& in);

  private:
    AdamConfig config_;
    int dim_ = 0;
    std::vector<float> moments_;  ///< the first moments, then the second moments
    std::uint32_t step_ = 0;
};

}  // namespace shine
