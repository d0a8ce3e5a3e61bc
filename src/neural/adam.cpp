#include "shine/optim/adam.hpp"

namespace shine {

const AdamBiasCorrection& RowAdam::bias_for_step(std::uint32_t step) {
    while (bias_by_step_.size() < step) {
        bias_by_step_.emplace_back(config_, static_cast<std::uint32_t>(bias_by_step_.size() + 1));
    }
    return bias_by_step_[step - 1];
}

void RowAdam::resize(std::size_t num_rows) {
    m_.resize(num_rows * row_dim_, 0.0f);
    v_.resize(num_rows * row_dim_, 0.0f);
    steps_.resize(num_rows, 0);
}

void RowAdam::step_rows(float* params, const float* grads, const std::vector<std::int32_t>& rows) {
    for (const std::int32_t row : rows) {
        const AdamBiasCorrection& bias = bias_for_step(++steps_[row]);
        const std::size_t base = std::size_t(row) * row_dim_;
        for (int i = 0; i < row_dim_; ++i) {
            adam_update(params[base + i], m_[base + i], v_[base + i], grads[base + i], config_,
                        bias);
        }
    }
}

void RowAdam::step_all(float* params, const float* grads) {
    for (std::size_t row = 0; row < steps_.size(); ++row) {
        const AdamBiasCorrection& bias = bias_for_step(++steps_[row]);
        const std::size_t base = row * row_dim_;
        for (int i = 0; i < row_dim_; ++i) {
            adam_update(params[base + i], m_[base + i], v_[base + i], grads[base + i], config_,
                        bias);
        }
    }
}

std::size_t RowAdam::memory_bytes() const {
    return (m_.size() + v_.size()) * sizeof(float) + steps_.size() * sizeof(std::uint32_t);
}

}  // namespace shine
