#include "shine/model/batched_decoder.hpp"

#include "shine/core/cpu_features.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define SHINE_HAVE_AVX_DECODER_KERNELS 1
#endif

namespace shine {
namespace {
using RowMajorMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using ConstWeights = Eigen::Map<const RowMajorMatrix>;
using Weights = Eigen::Map<RowMajorMatrix>;
using ConstBias = Eigen::Map<const Eigen::VectorXf>;
using Bias = Eigen::Map<Eigen::VectorXf>;

#if defined(SHINE_HAVE_AVX_DECODER_KERNELS)
// The layers' products with AVX, eight rows of the result to a register. Eigen computes
// `dst.noalias() = lhs * rhs` for these sizes as dst = 0, then dst += 1 * C, where C sums
// lhs(r, d) * rhs(d, b) over d in order, one multiplication and one addition each (the default
// build has no FMA), starting from zero. The kernels below do the same operations in the same
// order on 8 rows at once instead of 4, and then apply the layer's bias and ReLU, or the ReLU
// mask of the backward pass, as Eigen's element-wise expressions do: the same bits
// (tests/test_model_batched_decoder.cpp compares both with the AVX kernels switched off).

/// What follows the product in a column of the result.
enum class Epilogue {
    kBiasRelu,  ///< forward through a hidden layer: relu(product + bias)
    kMask,      ///< backward: the product where the layer's activation is > 0, else 0
    kNone,      ///< backward to the input features: the product
};

/// Column b of the result from its G sums: the epilogue, then the store.
template <int G, Epilogue E>
__attribute__((target("avx"))) inline void finish_column(const __m256* sums,
                                                         const __m256* bias_rows,
                                                         const float* activation, float* out) {
    const __m256 zero = _mm256_setzero_ps();
    for (int g = 0; g < G; ++g) {
        __m256 v = _mm256_add_ps(sums[g], zero);  // dst = 0, then dst += 1 * C
        if constexpr (E == Epilogue::kBiasRelu) {
            v = _mm256_add_ps(v, bias_rows[g]);
            v = _mm256_max_ps(zero, v);  // (0 > v) ? 0 : v, as Eigen's cwiseMax(0)
        } else if constexpr (E == Epilogue::kMask) {
            const __m256 a = _mm256_loadu_ps(activation + 8 * g);
            v = _mm256_and_ps(_mm256_cmp_ps(a, zero, _CMP_GT_OQ), v);
        }
        _mm256_storeu_ps(out + 8 * g, v);
    }
}

/// out(:, b) = epilogue(sum over d of M(d, :) * in(d, b)) for the B columns of `in` (depth D,
/// column-major) into `out` (8 G rows, column-major; `activation` alike for kMask). M is D rows
/// of 8 G floats, row-major: row d holds the factors of in(d, b) for every row of the result.
template <int G, Epilogue E>
__attribute__((target("avx"))) void layer_product_avx(const float* M, int D, const float* in,
                                                      Eigen::Index B, const float* bias,
                                                      const float* activation, float* out) {
    constexpr int R = 8 * G;
    __m256 bias_rows[G];
    for (int g = 0; g < G; ++g) {
        bias_rows[g] =
            E == Epilogue::kBiasRelu ? _mm256_loadu_ps(bias + 8 * g) : _mm256_setzero_ps();
    }
    Eigen::Index b = 0;
    for (; b + 1 < B; b += 2) {  // two columns share each row of M
        const float* x0 = in + b * D;
        const float* x1 = x0 + D;
        __m256 sum0[G], sum1[G];
        for (int g = 0; g < G; ++g) sum0[g] = sum1[g] = _mm256_setzero_ps();
        for (int d = 0; d < D; ++d) {
            const __m256 s0 = _mm256_set1_ps(x0[d]);
            const __m256 s1 = _mm256_set1_ps(x1[d]);
            for (int g = 0; g < G; ++g) {
                const __m256 m = _mm256_loadu_ps(M + d * R + 8 * g);
                sum0[g] = _mm256_add_ps(sum0[g], _mm256_mul_ps(m, s0));
                sum1[g] = _mm256_add_ps(sum1[g], _mm256_mul_ps(m, s1));
            }
        }
        const float* a0 = E == Epilogue::kMask ? activation + b * R : nullptr;
        finish_column<G, E>(sum0, bias_rows, a0, out + b * R);
        finish_column<G, E>(sum1, bias_rows, a0 ? a0 + R : nullptr, out + (b + 1) * R);
    }
    for (; b < B; ++b) {
        const float* x = in + b * D;
        __m256 sum[G];
        for (int g = 0; g < G; ++g) sum[g] = _mm256_setzero_ps();
        for (int d = 0; d < D; ++d) {
            const __m256 s = _mm256_set1_ps(x[d]);
            for (int g = 0; g < G; ++g) {
                sum[g] =
                    _mm256_add_ps(sum[g], _mm256_mul_ps(_mm256_loadu_ps(M + d * R + 8 * g), s));
            }
        }
        finish_column<G, E>(sum, bias_rows, E == Epilogue::kMask ? activation + b * R : nullptr,
                            out + b * R);
    }
}

/// The kernel for `rows` rows of the result, a size avx_layer() accepts (8, 16, 24 or 32).
template <Epilogue E>
void layer_product(int rows, const float* M, int D, const float* in, Eigen::Index B,
                   const float* bias, const float* activation, float* out) {
    switch (rows / 8) {
        case 1:
            return layer_product_avx<1, E>(M, D, in, B, bias, activation, out);
        case 2:
            return layer_product_avx<2, E>(M, D, in, B, bias, activation, out);
        case 3:
            return layer_product_avx<3, E>(M, D, in, B, bias, activation, out);
        default:
            return layer_product_avx<4, E>(M, D, in, B, bias, activation, out);
    }
}

/// Whether the AVX kernels compute a layer's product with `rows` rows of the result, `depth`
/// terms a sum and B columns: where Eigen takes its blocked product (gebp), whose order of
/// operations they follow. Eigen takes a matrix-vector product for one column and a
/// coefficient-wise one when depth + rows + B < 20 (EIGEN_GEMM_TO_COEFFBASED_THRESHOLD).
bool avx_layer(int rows, int depth, Eigen::Index B) {
    return rows % 8 == 0 && rows >= 8 && rows <= 32 && B >= 2 && depth + rows + B >= 20 &&
           use_avx_f16c();
}
#endif
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
#if defined(SHINE_HAVE_AVX_DECODER_KERNELS)
        const Eigen::Index B = batch.activations[k].cols();
        if (k + 1 < K && avx_layer(dims[k + 1], dims[k], B)) {
            // The kernel reads W by input: its transpose, dims[k] rows of dims[k + 1].
            batch.transposed_weights = W.transpose();
            out.resize(dims[k + 1], B);
            layer_product<Epilogue::kBiasRelu>(dims[k + 1], batch.transposed_weights.data(),
                                               dims[k], batch.activations[k].data(), B, b.data(),
                                               nullptr, out.data());
            continue;
        }
#endif
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
#if defined(SHINE_HAVE_AVX_DECODER_KERNELS)
        if (avx_layer(dims[k], dims[k + 1], B)) {
            // W's rows are the factors of U_{k+1}'s rows: row-major W is the kernel's M.
            target.resize(dims[k], B);
            if (k > 0) {
                layer_product<Epilogue::kMask>(dims[k], W.data(), dims[k + 1],
                                               batch.upstream[k + 1].data(), B, nullptr,
                                               batch.activations[k].data(), target.data());
            } else {
                layer_product<Epilogue::kNone>(dims[k], W.data(), dims[k + 1],
                                               batch.upstream[k + 1].data(), B, nullptr, nullptr,
                                               target.data());
            }
            continue;
        }
#endif
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
