#include "shine/model/decoder.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <random>

#include "shine/core/error.hpp"

namespace shine {

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
