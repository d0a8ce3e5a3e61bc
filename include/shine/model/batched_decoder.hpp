// The decoder (decoder.hpp) on a batch of samples at once: the same forward pass, input gradient
// h = df/dF and parameter gradients as Decoder's per-sample calls, written as matrix products over
// the batch (one column per sample) so that blocked products do the work instead of one
// matrix-vector product per sample. Equal to the per-sample calls up to float rounding
// (tests/test_model_batched_decoder.cpp). The hidden layers' forward products and the input
// gradient's products run in AVX kernels where the CPU has AVX (8, 16, 24 or 32 rows of result):
// Eigen's operations in Eigen's order, so the same bits as Eigen's products.
//
// With A_0 = X (L x B, the batch's features), for the K weight layers
//   A_{k+1} = relu(W_k A_k + b_k)        (no ReLU on the output, f = A_K, 1 x B)
//   U_K = 1,  U_k = M_k (.) W_k^T U_{k+1}  (M_k the ReLU masks of A_k),  H = W_0^T U_1  (L x B)
// and for per-sample dL/df = g (1 x B) and a loss on h with dL/dh = E (L x B, may be absent):
//   Q_0 = E, C_1 = W_0 E, Q_k = M_k (.) C_k, C_{k+1} = W_k Q_k      (the "double backward")
//   dW_k += U_{k+1} (A_k diag(g) + Q_k)^T,   db_k += U_{k+1} g^T.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "shine/model/decoder.hpp"

namespace shine {

/// Scratch space of one batch: activations and upstream gradients, kept for the backward passes.
struct DecoderBatch {
    std::vector<Eigen::MatrixXf> activations;  ///< A_0 ... A_K (A_0: the input features)
    std::vector<Eigen::MatrixXf> upstream;     ///< U_1 ... U_K (index k holds U_k; U_0 unused)
    Eigen::MatrixXf input_gradient;            ///< H = df/dF, L x B, after input_gradient()
    Eigen::MatrixXf product;                   ///< scratch
    Eigen::MatrixXf carry;                     ///< scratch (C_k of the double backward)
    /// Scratch: a layer's weights transposed, for the AVX kernels of forward_batch().
    Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> transposed_weights;

    /// The batch's input features, L x B: fill its columns before forward().
    Eigen::MatrixXf& features() { return activations.front(); }
    /// f, 1 x B, after forward().
    const Eigen::MatrixXf& output() const { return activations.back(); }
};

/// Sizes `batch` for `batch_size` samples of `decoder` (keeps capacity across calls).
void prepare_batch(const Decoder& decoder, int batch_size, DecoderBatch& batch);

/// f for every column of batch.features(); keeps the activations.
void forward_batch(const Decoder& decoder, DecoderBatch& batch);

/// After forward_batch(): H = df/dF into batch.input_gradient, and the upstream gradients.
void input_gradient_batch(const Decoder& decoder, DecoderBatch& batch);

/// After input_gradient_batch(): adds to `param_grads` (Decoder::params() layout) the gradient of
/// sum_b [ L_b ] for per-sample dL_b/df_b = grad_output(b) and, when `grad_input_gradient` is not
/// null, dL_b/dh_b = its column b (L x B).
void accumulate_param_gradient_batch(const Decoder& decoder, DecoderBatch& batch,
                                     const Eigen::RowVectorXf& grad_output,
                                     const Eigen::MatrixXf* grad_input_gradient,
                                     float* param_grads);

}  // namespace shine
