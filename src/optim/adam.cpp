#include "shine/optim/adam.hpp"

#include "shine/io/binary_stream.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace shine {

void AdamSchedule::reserve_steps(std::uint32_t max_step) {
    while (bias_by_step_.size() < max_step) {
        bias_by_step_.emplace_back(config_, static_cast<std::uint32_t>(bias_by_step_.size() + 1));
    }
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

DenseAdam::DenseAdam(const AdamConfig& config, int dim)
    : config_(config), dim_(dim), moments_(2 * std::size_t(dim), 0.0f) {}

void DenseAdam::step(float* params, const float* grads) {
    const AdamBiasCorrection bias(config_, ++step_);
    adam_update_row(params, grads, moments_.data(), moments_.data() + dim_, dim_, config_, bias);
}

std::size_t DenseAdam::memory_bytes() const {
    return moments_.size() * sizeof(float) + sizeof(step_);
}

// The layout of a table of one row (row size, moments, one step count), which checkpoints have
// always used for the decoder.
void DenseAdam::save(BinaryWriter& out) const {
    out.value<std::int32_t>(dim_);
    out.array(moments_);
    out.array(std::vector<std::uint32_t>{step_});
}

void DenseAdam::load(BinaryReader& in) {
    const auto dim = in.value<std::int32_t>("Adam row size");
    if (dim != dim_) {
        in.fail("Adam row size",
                std::to_string(dim) + " differs from this map's " + std::to_string(dim_));
    }
    std::vector<float> moments = in.array<float>("Adam moments");
    const std::vector<std::uint32_t> steps = in.array<std::uint32_t>("Adam step counts");
    if (steps.size() != 1) in.fail("decoder Adam state", "is not a single row");
    if (moments.size() != 2 * std::size_t(dim_)) {
        in.fail("Adam moments", "do not match the row size " + std::to_string(dim_));
    }
    moments_ = std::move(moments);
    step_ = steps[0];
}

}  // namespace shine
