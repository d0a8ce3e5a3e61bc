#include "shine/model/batched_decoder.hpp"

namespace shine {
namespace {
using RowMajorMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using ConstWeights = Eigen::Map<const RowMajorMatrix>;
using Weights = Eigen::Map<RowMajorMatrix>;
using ConstBias = Eigen::Map<const Eigen::VectorXf>;
using Bias = Eigen::Map<Eigen::VectorXf>;
}  // namespace

void prepare_batch(const Decoder& decoder, int batch_size, DecoderBatch& batch) {
    const std::vector<int>& dims = decoder.layer_dims();
    const int K = decoder.num_layers();
    batch.activations.resize(K + 1);
    batch.upstream.resize(K + 1);
    for (int k = 0; k <= K; ++k) {
        batch.activations[k].resize(dims[k], batch_size);
        batch.upstream[k].resize(dims[k], batch_size);
    }
    batch.input_gradient.resize(dims[0], batch_size);
}

void forward_batch(const Decoder& decoder, DecoderBatch& batch) {
    const std::vector<int>& dims = decoder.layer_dims();
    const float* params = decoder.params().data();
    const int K = decoder.num_layers();
    for (int k = 0; k < K; ++k) {
        const ConstWeights W(params + decoder.weight_offset(k), dims[k + 1], dims[k]);
        const ConstBias b(params + decoder.bias_offset(k), dims[k + 1]);
        Eigen::MatrixXf& out = batch.activations[k + 1];
        out.noalias() = W * batch.activations[k];
        out.colwise() += b;
        if (k + 1 < K) out = out.cwiseMax(0.0f);
    }
}

void input_gradient_batch(const Decoder& decoder, DecoderBatch& batch) {
    const std::vector<int>& dims = decoder.layer_dims();
    const float* params = decoder.params().data();
    const int K = decoder.num_layers();
    const Eigen::Index B = batch.activations[0].cols();
    batch.upstream[K].setOnes(dims[K], B);
    for (int k = K - 1; k >= 0; --k) {
        const ConstWeights W(params + decoder.weight_offset(k), dims[k + 1], dims[k]);
        Eigen::MatrixXf& target = k == 0 ? batch.input_gradient : batch.upstream[k];
        target.noalias() = W.transpose() * batch.upstream[k + 1];
        if (k > 0) {
            // ReLU mask of the layer's activations (a = 0 where the pre-activation was <= 0).
            target = (batch.activations[k].array() > 0.0f).select(target, 0.0f);
        }
    }
}

void accumulate_param_gradient_batch(const Decoder& decoder, DecoderBatch& batch,
                                     const Eigen::RowVectorXf& grad_output,
                                     const Eigen::MatrixXf* grad_input_gradient,
                                     float* param_grads) {
    const std::vector<int>& dims = decoder.layer_dims();
    const float* params = decoder.params().data();
    const int K = decoder.num_layers();
    for (int k = 0; k < K; ++k) {
        // P_k = A_k diag(g) + Q_k; Q_0 = E and Q_k = M_k (.) C_k, C_{k+1} = W_k Q_k.
        Eigen::MatrixXf& P = batch.product;
        P.noalias() = batch.activations[k] * grad_output.asDiagonal();
        if (grad_input_gradient) {
            if (k == 0) {
                P += *grad_input_gradient;
            } else {
                batch.carry = (batch.activations[k].array() > 0.0f).select(batch.carry, 0.0f);
                P += batch.carry;
            }
        }
        const Eigen::MatrixXf& U = batch.upstream[k + 1];
        Weights dW(param_grads + decoder.weight_offset(k), dims[k + 1], dims[k]);
        Bias db(param_grads + decoder.bias_offset(k), dims[k + 1]);
        dW.noalias() += U * P.transpose();
        db.noalias() += U * grad_output.transpose();
        if (grad_input_gradient && k + 1 < K) {
            const ConstWeights W(params + decoder.weight_offset(k), dims[k + 1], dims[k]);
            // C_{k+1} = W_k Q_k (Q_0 = E; for k > 0 the masked carry is Q_k).
            Eigen::MatrixXf next = W * (k == 0 ? *grad_input_gradient : batch.carry);
            batch.carry.swap(next);
        }
    }
}

}  // namespace shine
