#include "shine/model/decoder.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <random>

#include "shine/core/cpu_features.hpp"
#include "shine/core/error.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define SHINE_HAVE_AVX_LANE_KERNELS 1
#endif

namespace shine {
namespace {

#if defined(SHINE_HAVE_AVX_LANE_KERNELS)
static_assert(kDecoderLanes == 8, "the AVX lane kernels hold the lanes in one register");

// Decoder::forward_lanes() and input_gradient_lanes() with the 8 lanes in one AVX register
// instead of two SSE registers: the same multiplications and additions in the same order (no
// FMA), and the same ReLU selections, so the same bits (tests/test_model_decoder_lanes.cpp
// compares every lane with forward() and input_gradient()).

/// The layers of forward_lanes() over the lanes' activations `a` (a_0 filled), laid out as
/// act_offset says.
__attribute__((target("avx"))) void forward_lanes_avx(const float* params,
                                                      const std::vector<int>& dims,
                                                      const std::vector<std::size_t>& w_offset,
                                                      const std::vector<std::size_t>& b_offset,
                                                      const std::vector<std::size_t>& act_offset,
                                                      float* a) {
    constexpr int S = kDecoderLanes;
    const int K = static_cast<int>(dims.size()) - 1;
    const __m256 zero = _mm256_setzero_ps();
    for (int k = 0; k < K; ++k) {
        const float* W = params + w_offset[k];
        const float* b = params + b_offset[k];
        const float* in = a + act_offset[k] * S;
        float* next = a + act_offset[k + 1] * S;
        const int n_in = dims[k], n_out = dims[k + 1];
        const bool hidden = k + 1 < K;
        for (int i = 0; i < n_out; ++i) {
            const float* row = W + std::size_t(i) * n_in;
            __m256 z = _mm256_set1_ps(b[i]);
            for (int j = 0; j < n_in; ++j) {
                z = _mm256_add_ps(z, _mm256_mul_ps(_mm256_set1_ps(row[j]),
                                                   _mm256_loadu_ps(in + std::size_t(j) * S)));
            }
            if (hidden) z = _mm256_andnot_ps(_mm256_cmp_ps(z, zero, _CMP_LT_OQ), z);
            _mm256_storeu_ps(next + std::size_t(i) * S, z);
        }
    }
}

/// target_j += row_i[j] * g_i over the rows i of W in order, for the 8 targets j0 .. j0 + 7 held
/// in registers (the lanes version adds into memory in the same order).
__attribute__((target("avx"))) inline void add_rows_avx8(const float* W, int n_in, int n_out,
                                                         const float* u_next, int j0,
                                                         float* target) {
    constexpr int S = kDecoderLanes;
    __m256 t[8];
    for (int jj = 0; jj < 8; ++jj) t[jj] = _mm256_loadu_ps(target + std::size_t(j0 + jj) * S);
    for (int i = 0; i < n_out; ++i) {
        const __m256 g = _mm256_loadu_ps(u_next + std::size_t(i) * S);
        const float* row = W + std::size_t(i) * n_in + j0;
        for (int jj = 0; jj < 8; ++jj) {
            t[jj] = _mm256_add_ps(t[jj], _mm256_mul_ps(_mm256_set1_ps(row[jj]), g));
        }
    }
    for (int jj = 0; jj < 8; ++jj) _mm256_storeu_ps(target + std::size_t(j0 + jj) * S, t[jj]);
}

/// input_gradient_lanes() after forward_lanes_avx(): `a` the lanes' activations, `u` the
/// upstream values, h into input_gradient.
__attribute__((target("avx"))) void input_gradient_lanes_avx(
    const float* params, const std::vector<int>& dims, const std::vector<std::size_t>& w_offset,
    const std::vector<std::size_t>& act_offset, const float* a, float* u, float* input_gradient) {
    constexpr int S = kDecoderLanes;
    const int K = static_cast<int>(dims.size()) - 1;
    const __m256 zero = _mm256_setzero_ps();
    _mm256_storeu_ps(u + act_offset[K] * S, _mm256_set1_ps(1.0f));
    for (int k = K - 1; k >= 0; --k) {
        const float* W = params + w_offset[k];
        const float* u_next = u + act_offset[k + 1] * S;
        const int n_in = dims[k], n_out = dims[k + 1];
        float* target = (k == 0) ? input_gradient : u + act_offset[k] * S;
        std::fill(target, target + std::size_t(n_in) * S, 0.0f);
        int j0 = 0;
        for (; j0 + 8 <= n_in; j0 += 8) add_rows_avx8(W, n_in, n_out, u_next, j0, target);
        for (int i = 0; i < n_out && j0 < n_in; ++i) {  // the last n_in mod 8 targets
            const __m256 g = _mm256_loadu_ps(u_next + std::size_t(i) * S);
            const float* row = W + std::size_t(i) * n_in;
            for (int j = j0; j < n_in; ++j) {
                float* t = target + std::size_t(j) * S;
                _mm256_storeu_ps(
                    t, _mm256_add_ps(_mm256_loadu_ps(t), _mm256_mul_ps(_mm256_set1_ps(row[j]), g)));
            }
        }
        if (k > 0) {
            const float* act = a + act_offset[k] * S;
            for (int j = 0; j < n_in; ++j) {
                float* t = target + std::size_t(j) * S;
                const __m256 off =
                    _mm256_cmp_ps(_mm256_loadu_ps(act + std::size_t(j) * S), zero, _CMP_LE_OQ);
                _mm256_storeu_ps(t, _mm256_andnot_ps(off, _mm256_loadu_ps(t)));  // ReLU mask
            }
        }
    }
}
#endif

}  // namespace

Decoder::Decoder(const DecoderConfig& config) : config_(config) {
    if (config.input_dim < 1) throw ConfigError("decoder input_dim must be >= 1");
    dims_.push_back(config.input_dim);
    for (int h : config.hidden_dims) {
        if (h < 1 || h > 1024) {
            throw ConfigError("decoder hidden layer sizes must be in [1, 1024], got " +
                              std::to_string(h));
        }
        dims_.push_back(h);
    }
    dims_.push_back(1);
    std::size_t offset = 0, act = 0;
    for (int k = 0; k < num_layers(); ++k) {
        w_offset_.push_back(offset);
        offset += std::size_t(dims_[k + 1]) * dims_[k];
        b_offset_.push_back(offset);
        offset += dims_[k + 1];
    }
    for (int d : dims_) {
        act_offset_.push_back(act);
        act += d;
    }
    params_.assign(offset, 0.0f);
    // PyTorch-like default: U(-1/sqrt(fan_in), 1/sqrt(fan_in)) for weights and biases.
    std::mt19937_64 rng(config.seed);
    for (int k = 0; k < num_layers(); ++k) {
        const float bound = 1.0f / std::sqrt(static_cast<float>(dims_[k]));
        std::uniform_real_distribution<float> uniform(-bound, bound);
        for (std::size_t i = w_offset_[k]; i < b_offset_[k] + dims_[k + 1]; ++i) {
            params_[i] = uniform(rng);
        }
    }
}

void Decoder::prepare(DecoderWorkspace& ws) const {
    ws.activations.assign(act_offset_.back() + dims_.back(), 0.0f);
    ws.upstream.assign(act_offset_.back() + dims_.back(), 0.0f);
    int widest = 0;
    for (int d : dims_) widest = std::max(widest, d);
    ws.scratch.assign(2 * widest, 0.0f);
}

float Decoder::forward(const float* feature, DecoderWorkspace& ws) const {
    if (ws.activations.size() != act_offset_.back() + dims_.back()) prepare(ws);
    float* a = ws.activations.data();
    std::copy(feature, feature + dims_[0], a);
    const int K = num_layers();
    for (int k = 0; k < K; ++k) {
        const float* W = params_.data() + w_offset_[k];
        const float* b = params_.data() + b_offset_[k];
        const float* in = a + act_offset_[k];
        float* out = a + act_offset_[k + 1];
        const int n_in = dims_[k], n_out = dims_[k + 1];
        for (int i = 0; i < n_out; ++i) {
            const float* row = W + std::size_t(i) * n_in;
            float z = b[i];
            for (int j = 0; j < n_in; ++j) z += row[j] * in[j];
            out[i] = (k + 1 < K) ? std::max(z, 0.0f) : z;
        }
    }
    return a[act_offset_[K]];
}

void Decoder::forward_lanes(const float* features, float* out, DecoderWorkspace& ws) const {
    // One fixed-size Eigen array per activation: Eigen keeps it in vector registers, and its
    // element-wise products and sums are forward()'s operations in every lane.
    using Lanes = Eigen::Array<float, kDecoderLanes, 1>;
    constexpr int S = kDecoderLanes;
    const std::size_t values = (act_offset_.back() + dims_.back()) * S;
    if (ws.lanes.size() != values) ws.lanes.assign(values, 0.0f);
    float* a = ws.lanes.data();
    std::copy(features, features + std::size_t(dims_[0]) * S, a);
    const int K = num_layers();
#if defined(SHINE_HAVE_AVX_LANE_KERNELS)
    if (use_avx_f16c()) {
        forward_lanes_avx(params_.data(), dims_, w_offset_, b_offset_, act_offset_, a);
        std::copy(a + act_offset_[K] * S, a + act_offset_[K] * S + S, out);
        return;
    }
#endif
    for (int k = 0; k < K; ++k) {
        const float* W = params_.data() + w_offset_[k];
        const float* b = params_.data() + b_offset_[k];
        const float* in = a + act_offset_[k] * S;
        float* next = a + act_offset_[k + 1] * S;
        const int n_in = dims_[k], n_out = dims_[k + 1];
        const bool hidden = k + 1 < K;
        for (int i = 0; i < n_out; ++i) {
            const float* row = W + std::size_t(i) * n_in;
            // forward()'s sum, z += w_ij * a_j in order of j, in every lane.
            Lanes z = Lanes::Constant(b[i]);
            for (int j = 0; j < n_in; ++j) z += row[j] * Eigen::Map<const Lanes>(in + j * S);
            Eigen::Map<Lanes> o(next + std::size_t(i) * S);
            if (hidden) {
                o = (z < 0.0f).select(Lanes::Zero(), z);  // std::max(z, 0.0f), -0 and NaN included
            } else {
                o = z;
            }
        }
    }
    std::copy(a + act_offset_[K] * S, a + act_offset_[K] * S + S, out);
}

void Decoder::input_gradient(DecoderWorkspace& ws, float* input_gradient) const {
    const int K = num_layers();
    const float* a = ws.activations.data();
    float* u = ws.upstream.data();
    u[act_offset_[K]] = 1.0f;
    // u_k = m_k (.) W_k^T u_{k+1} for the hidden layers, then h = W_0^T u_1.
    for (int k = K - 1; k >= 0; --k) {
        const float* W = params_.data() + w_offset_[k];
        const float* u_next = u + act_offset_[k + 1];
        const int n_in = dims_[k], n_out = dims_[k + 1];
        float* target = (k == 0) ? input_gradient : u + act_offset_[k];
        std::fill(target, target + n_in, 0.0f);
        for (int i = 0; i < n_out; ++i) {
            const float g = u_next[i];
            if (g == 0.0f) continue;
            const float* row = W + std::size_t(i) * n_in;
            for (int j = 0; j < n_in; ++j) target[j] += row[j] * g;
        }
        if (k > 0) {
            const float* act = a + act_offset_[k];
            for (int j = 0; j < n_in; ++j) {
                if (act[j] <= 0.0f) target[j] = 0.0f;  // ReLU mask
            }
        }
    }
}

void Decoder::input_gradient_lanes(DecoderWorkspace& ws, float* input_gradient) const {
    using Lanes = Eigen::Array<float, kDecoderLanes, 1>;
    constexpr int S = kDecoderLanes;
    const std::size_t values = (act_offset_.back() + dims_.back()) * S;
    if (ws.lanes_upstream.size() != values) ws.lanes_upstream.assign(values, 0.0f);
    const float* a = ws.lanes.data();
    float* u = ws.lanes_upstream.data();
#if defined(SHINE_HAVE_AVX_LANE_KERNELS)
    if (use_avx_f16c()) {
        input_gradient_lanes_avx(params_.data(), dims_, w_offset_, act_offset_, a, u,
                                 input_gradient);
        return;
    }
#endif
    const int K = num_layers();
    Eigen::Map<Lanes>(u + std::size_t(act_offset_[K]) * S).setConstant(1.0f);
    for (int k = K - 1; k >= 0; --k) {
        const float* W = params_.data() + w_offset_[k];
        const float* u_next = u + std::size_t(act_offset_[k + 1]) * S;
        const int n_in = dims_[k], n_out = dims_[k + 1];
        float* target = (k == 0) ? input_gradient : u + std::size_t(act_offset_[k]) * S;
        std::fill(target, target + std::size_t(n_in) * S, 0.0f);
        for (int i = 0; i < n_out; ++i) {
            const Eigen::Map<const Lanes> g(u_next + std::size_t(i) * S);
            const float* row = W + std::size_t(i) * n_in;
            for (int j = 0; j < n_in; ++j) {
                Eigen::Map<Lanes>(target + std::size_t(j) * S) += row[j] * g;
            }
        }
        if (k > 0) {
            const float* act = a + std::size_t(act_offset_[k]) * S;
            for (int j = 0; j < n_in; ++j) {
                Eigen::Map<Lanes> t(target + std::size_t(j) * S);
                t = (Eigen::Map<const Lanes>(act + std::size_t(j) * S) <= 0.0f)
                        .select(Lanes::Zero(), t);  // ReLU mask
            }
        }
    }
}

void Decoder::accumulate_param_gradient(const DecoderWorkspace& ws, float grad_output,
                                        float* param_grads) const {
    const int K = num_layers();
    const float* a = ws.activations.data();
    const float* u = ws.upstream.data();
    for (int k = 0; k < K; ++k) {
        float* dW = param_grads + w_offset_[k];
        float* db = param_grads + b_offset_[k];
        const float* in = a + act_offset_[k];
        const float* u_next = u + act_offset_[k + 1];
        const int n_in = dims_[k], n_out = dims_[k + 1];
        for (int i = 0; i < n_out; ++i) {
            const float g = grad_output * u_next[i];
            if (g == 0.0f) continue;
            db[i] += g;
            float* row = dW + std::size_t(i) * n_in;
            for (int j = 0; j < n_in; ++j) row[j] += g * in[j];
        }
    }
}

void Decoder::accumulate_input_gradient_param_gradient(DecoderWorkspace& ws, const float* grad_h,
                                                       float* param_grads) const {
    // h = W_0^T u_1 and u_k = m_k (.) W_k^T u_{k+1}: with c_1 = de/du_1 = W_0 grad_h,
    // dW_0 += u_1 grad_h^T; then q_k = m_k (.) c_k, dW_k += u_{k+1} q_k^T, c_{k+1} = W_k q_k.
    // Biases do not influence h.
    const int K = num_layers();
    const float* a = ws.activations.data();
    const float* u = ws.upstream.data();
    float* c = ws.scratch.data();
    float* c_next = ws.scratch.data() + ws.scratch.size() / 2;
    {
        const float* W = params_.data() + w_offset_[0];
        float* dW = param_grads + w_offset_[0];
        const float* u1 = u + act_offset_[1];
        const int n_in = dims_[0], n_out = dims_[1];
        for (int i = 0; i < n_out; ++i) {
            const float* row = W + std::size_t(i) * n_in;
            float* drow = dW + std::size_t(i) * n_in;
            float ci = 0.0f;
            for (int j = 0; j < n_in; ++j) {
                ci += row[j] * grad_h[j];
                drow[j] += u1[i] * grad_h[j];
            }
            c[i] = ci;
        }
    }
    for (int k = 1; k < K; ++k) {
        const float* W = params_.data() + w_offset_[k];
        float* dW = param_grads + w_offset_[k];
        const float* act = a + act_offset_[k];
        const float* u_next = u + act_offset_[k + 1];
        const int n_in = dims_[k], n_out = dims_[k + 1];
        for (int j = 0; j < n_in; ++j) {
            if (act[j] <= 0.0f) c[j] = 0.0f;  // q_k = m_k (.) c_k
        }
        for (int i = 0; i < n_out; ++i) {
            const float* row = W + std::size_t(i) * n_in;
            float* drow = dW + std::size_t(i) * n_in;
            float ci = 0.0f;
            for (int j = 0; j < n_in; ++j) {
                ci += row[j] * c[j];
                drow[j] += u_next[i] * c[j];
            }
            c_next[i] = ci;
        }
        std::swap(c, c_next);
    }
}

}  // namespace shine
