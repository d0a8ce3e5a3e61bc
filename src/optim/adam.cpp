#include "shine/optim/adam.hpp"

#include "shine/io/binary_stream.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace shine {

const AdamBiasCorrection& RowAdam::bias_for_step(std::uint32_t step) {
    while (bias_by_step_.size() < step) {
        bias_by_step_.emplace_back(config_, static_cast<std::uint32_t>(bias_by_step_.size() + 1));
    }
    return bias_by_step_[step - 1];
}

void RowAdam::resize(std::size_t num_rows) {
    moments_.resize(num_rows * 2 * row_dim_, 0.0f);
    steps_.resize(num_rows, 0);
}

void adam_update_row(float* param, const float* grad, float* m, float* v, int dim,
                     const AdamConfig& config, const AdamBiasCorrection& bias) {
    // adam_update() on a whole row, 4 floats at a time with SSE: the same IEEE operations in the
    // same order as the scalar code (so bit-identical results), but SIMD square roots and
    // divisions, which the scalar loop does not get (std::sqrt may set errno, so the compiler
    // keeps it scalar). Eigen's .sqrt() is not used: with EIGEN_FAST_MATH it is approximate.
    int i = 0;
#if defined(__SSE2__)
    const __m128 beta1 = _mm_set1_ps(config.beta1), beta2 = _mm_set1_ps(config.beta2);
    const __m128 one_minus_beta1 = _mm_set1_ps(1.0f - config.beta1);
    const __m128 one_minus_beta2 = _mm_set1_ps(1.0f - config.beta2);
    const __m128 lr = _mm_set1_ps(config.learning_rate), eps = _mm_set1_ps(config.epsilon);
    const __m128 inv_first = _mm_set1_ps(bias.inv_first);
    const __m128 inv_second = _mm_set1_ps(bias.inv_second);
    for (; i + 4 <= dim; i += 4) {
        const __m128 g = _mm_loadu_ps(grad + i);
        const __m128 m_new =
            _mm_add_ps(_mm_mul_ps(beta1, _mm_loadu_ps(m + i)), _mm_mul_ps(one_minus_beta1, g));
        const __m128 v_new = _mm_add_ps(_mm_mul_ps(beta2, _mm_loadu_ps(v + i)),
                                        _mm_mul_ps(_mm_mul_ps(one_minus_beta2, g), g));
        _mm_storeu_ps(m + i, m_new);
        _mm_storeu_ps(v + i, v_new);
        const __m128 step = _mm_div_ps(_mm_mul_ps(lr, _mm_mul_ps(m_new, inv_first)),
                                       _mm_add_ps(_mm_sqrt_ps(_mm_mul_ps(v_new, inv_second)), eps));
        _mm_storeu_ps(param + i, _mm_sub_ps(_mm_loadu_ps(param + i), step));
    }
#endif
    for (; i < dim; ++i) adam_update(param[i], m[i], v[i], grad[i], config, bias);
}

void RowAdam::update_row(float* param, const float* grad, std::size_t row) {
    const AdamBiasCorrection& bias = bias_for_step(++steps_[row]);
    float* m = moments_.data() + row * 2 * row_dim_;
    adam_update_row(param, grad, m, m + row_dim_, row_dim_, config_, bias);
}

void RowAdam::step_rows(float* params, const float* grads, const std::vector<std::int32_t>& rows) {
    for (const std::int32_t row : rows) {
        const std::size_t base = std::size_t(row) * row_dim_;
        update_row(params + base, grads + base, std::size_t(row));
    }
}

void RowAdam::step_listed_rows(float* params, const float* row_grads,
                               const std::vector<std::int32_t>& rows) {
    // Rows come in random order and the loop is bound by cache misses on the step counts,
    // moments and parameters: request them a few rows ahead.
    constexpr std::size_t kAhead = 8;
    for (std::size_t i = 0; i < rows.size(); ++i) {
        if (i + kAhead < rows.size()) {
            const std::size_t ahead = std::size_t(rows[i + kAhead]);
            __builtin_prefetch(steps_.data() + ahead, 1);
            __builtin_prefetch(moments_.data() + ahead * 2 * row_dim_, 1);
            __builtin_prefetch(params + ahead * row_dim_, 1);
        }
        const std::size_t row = std::size_t(rows[i]);
        update_row(params + row * row_dim_, row_grads + i * row_dim_, row);
    }
}

void RowAdam::step_all(float* params, const float* grads) {
    for (std::size_t row = 0; row < steps_.size(); ++row) {
        const std::size_t base = row * row_dim_;
        update_row(params + base, grads + base, row);
    }
}

std::size_t RowAdam::memory_bytes() const {
    return moments_.size() * sizeof(float) + steps_.size() * sizeof(std::uint32_t);
}

void RowAdam::save(BinaryWriter& out) const {
    out.value<std::int32_t>(row_dim_);
    out.array(moments_);
    out.array(steps_);
}

void RowAdam::load(BinaryReader& in) {
    const auto row_dim = in.value<std::int32_t>("Adam row size");
    if (row_dim != row_dim_) {
        in.fail("Adam row size",
                std::to_string(row_dim) + " differs from this map's " + std::to_string(row_dim_));
    }
    std::vector<float> moments = in.array<float>("Adam moments");
    std::vector<std::uint32_t> steps = in.array<std::uint32_t>("Adam step counts");
    if (moments.size() != steps.size() * 2 * static_cast<std::size_t>(row_dim_)) {
        in.fail("Adam moments",
                "do not match the " + std::to_string(steps.size()) + " step counts");
    }
    moments_ = std::move(moments);
    steps_ = std::move(steps);
}

}  // namespace shine
