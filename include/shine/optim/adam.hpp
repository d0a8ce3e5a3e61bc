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

/// Adam state for a parameter table of rows of `row_dim` floats that can grow.
class RowAdam {
  public:
    RowAdam() = default;
    RowAdam(const AdamConfig& config, int row_dim) : config_(config), row_dim_(row_dim) {}

    const AdamConfig& config() const { return config_; }
    void set_learning_rate(float lr) { config_.learning_rate = lr; }
    /// Grows the state to `num_rows` rows (new rows start with zero moments).
    void resize(std::size_t num_rows);
    /// Updates the listed rows of `params` with the matching rows of `grads`. Calls on disjoint
    /// row lists may run concurrently once reserve_steps() covers every row's next step count.
    void step_rows(float* params, const float* grads, const std::vector<std::int32_t>& rows);
    /// Precomputes the bias corrections up to step `max_step`, so that step_rows() only reads
    /// shared state for rows whose step count stays at or below it.
    void reserve_steps(std::uint32_t max_step) {
        if (max_step > 0) bias_for_step(max_step);
    }
    /// The bias corrections of step `step` (1-based), which reserve_steps() must cover.
    const AdamBiasCorrection& reserved_bias(std::uint32_t step) const {
        return bias_by_step_[step - 1];
    }
    /// As step_rows(), but the gradient of rows[i] is row_grads[i * row_dim, (i + 1) * row_dim):
    /// a compact buffer of the listed rows only (the trainer's reduction writes it).
    void step_listed_rows(float* params, const float* row_grads,
                          const std::vector<std::int32_t>& rows);
    /// Updates every row (dense use: the decoder as one row).
    void step_all(float* params, const float* grads);

    std::size_t num_rows() const { return steps_.size(); }
    std::vector<std::uint32_t>& steps() { return steps_; }
    std::size_t memory_bytes() const;

    /// The moments and per-row step counts (for a checkpoint); load() replaces them and throws
    /// IoError (via the reader) if the stored table's shape differs from this one's row_dim.
    void save(BinaryWriter& out) const;
    void load(BinaryReader& in);

  private:
    const AdamBiasCorrection& bias_for_step(std::uint32_t step);
    /// One row's update (Eigen arrays; see adam.cpp).
    void update_row(float* param, const float* grad, std::size_t row);

    AdamConfig config_;
    std::vector<AdamBiasCorrection> bias_by_step_;  ///< index step-1; pow() once per step value
    int row_dim_ = 1;
    /// Per row its first moments then its second moments (2 * row_dim floats): a row's state is
    /// one contiguous block (one cache line for 8-float features), since rows are visited in
    /// random order.
    std::vector<float> moments_;
    std::vector<std::uint32_t> steps_;
};

}  // namespace shine
