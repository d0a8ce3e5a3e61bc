// The shared MLP decoder phi: summed feature F (length L) -> signed distance in metres.
//
// Fully connected layers with ReLU on the hidden layers and a linear output (paper Sec. III-A; the
// default 8 -> 32 -> 32 -> 1). Besides the usual forward/backward, it provides the input gradient
// h = df/dF (for the Eikonal term, Eq. (3)) and the gradient of a loss on h with respect to the
// weights ("double backward"). Because ReLU's derivative is piecewise constant, h does not depend
// on F except through the activation masks, so the Eikonal loss reaches the weights only through h
// and reaches the features only through the feature Jacobian.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace shine {

/// Shape of the decoder.
struct DecoderConfig {
    int input_dim = 8;                        ///< L, the feature length
    std::vector<int> hidden_dims = {32, 32};  ///< M hidden layers
    std::uint64_t seed = 42;                  ///< initial weights
};

/// Per-thread scratch space of one forward pass, kept for the backward passes.
struct DecoderWorkspace {
    std::vector<float> activations;  ///< a_0 = F, a_1 ... a_M (post-ReLU)
    std::vector<float> upstream;     ///< u_k = df/dz_k for k = 1..K (u_K = 1)
    std::vector<float> scratch;
    std::vector<float> lanes;           ///< forward_lanes(): a_0 ... a_K of kDecoderLanes samples
    std::vector<float> lanes_upstream;  ///< input_gradient_lanes(): u_k of every lane
};

/// Samples that Decoder::forward_lanes() evaluates at once.
inline constexpr int kDecoderLanes = 8;

/// MLP with a flat parameter vector (weights row-major, then bias, layer by layer).
class Decoder {
  public:
    Decoder() = default;
    explicit Decoder(const DecoderConfig& config);

    const DecoderConfig& config() const { return config_; }
    int input_dim() const { return config_.input_dim; }
    std::size_t num_params() const { return params_.size(); }
    std::vector<float>& params() { return params_; }
    const std::vector<float>& params() const { return params_; }

    /// Sizes the workspace for this decoder.
    void prepare(DecoderWorkspace& ws) const;

    /// f(F); keeps activations in `ws` for the calls below.
    float forward(const float* feature, DecoderWorkspace& ws) const;

    /// f of kDecoderLanes samples at once, for evaluation only (bake, queries): feature l of
    /// lane s at features[l * kDecoderLanes + s], f of lane s into out[s]. Each lane does
    /// forward()'s arithmetic operation for operation, so its value is forward()'s bit for bit;
    /// the lanes share vector instructions.
    void forward_lanes(const float* features, float* out, DecoderWorkspace& ws) const;

    /// After forward(): h = df/dF into input_gradient (length L); fills ws.upstream.
    void input_gradient(DecoderWorkspace& ws, float* input_gradient) const;

    /// After forward_lanes(): h = df/dF of every lane, h_l of lane s at
    /// input_gradient[l * kDecoderLanes + s]. Each lane does input_gradient()'s operations in
    /// the same order (a row skipped there for a zero upstream value adds zeros here, which
    /// leaves every sum's bits as they are), so its h is input_gradient()'s bit for bit.
    void input_gradient_lanes(DecoderWorkspace& ws, float* input_gradient) const;

    /// After input_gradient(): adds dL/dparams for dL/df = grad_output into param_grads.
    void accumulate_param_gradient(const DecoderWorkspace& ws, float grad_output,
                                   float* param_grads) const;

    /// After input_gradient(): adds d e/d params for a loss e(h) with d e/d h = grad_h (length L).
    void accumulate_input_gradient_param_gradient(DecoderWorkspace& ws, const float* grad_h,
                                                  float* param_grads) const;

    /// Plain evaluation without keeping a workspace alive across calls.
    float evaluate(const float* feature, DecoderWorkspace& ws) const {
        return forward(feature, ws);
    }

    /// Number of weight layers K (hidden layers + the output layer).
    int num_layers() const { return static_cast<int>(dims_.size()) - 1; }
    /// Widths n_0 = L, hidden..., n_K = 1.
    const std::vector<int>& layer_dims() const { return dims_; }
    /// Start of W_k (n_{k+1} x n_k, row-major) and of b_k in params().
    std::size_t weight_offset(int k) const { return w_offset_[k]; }
    std::size_t bias_offset(int k) const { return b_offset_[k]; }

  private:
    DecoderConfig config_;
    std::vector<int> dims_;                ///< n_0 = L, hidden..., 1
    std::vector<std::size_t> w_offset_;    ///< start of W_k in params_
    std::vector<std::size_t> b_offset_;    ///< start of b_k in params_
    std::vector<std::size_t> act_offset_;  ///< start of a_k in the workspace
    std::vector<float> params_;
};

}  // namespace shine
