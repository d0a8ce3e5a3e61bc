#include "shine/model/batch_gradient.hpp"

#include <algorithm>
#include <type_traits>

#include "shine/core/cpu_features.hpp"
#include "shine/model/sdf_loss.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define SHINE_HAVE_F16C_KERNELS 1
#endif

namespace shine {
namespace {

/// F = sum_k w_k f_k and, for Eikonal samples, the Jacobian dF/dx = sum_k f_k dw_k^T, stored
/// axis-major (jacobian[a * dim + l] = dF_l/dx_a) so that the sum over the corners runs along
/// the features in vector registers. Both sums take the corners in order, as
/// gather_feature() and feature_jacobian() do. Dim > 0 fixes the feature size at compile time.
template <int Dim, typename T>
void gather_batch(BatchGradient& out, const T* table, int runtime_dim, Eigen::MatrixXf& X) {
    const int dim = Dim > 0 ? Dim : runtime_dim;
    constexpr int kCapacity = Dim > 0 ? Dim : kMaxFeatureDim;
    constexpr std::size_t kAhead = 2;
    const int stride = out.corner_stride;
    const std::size_t n = out.num_valid();
    for (std::size_t b = 0; b < n; ++b) {
        if (b + kAhead < n) {
            const std::int32_t* rows = out.rows.data() + (b + kAhead) * stride;
            for (int k = 0; k < out.corners[b + kAhead]; ++k) {
                __builtin_prefetch(table + std::size_t(rows[k]) * dim);
            }
        }
        const std::int32_t* rows = out.rows.data() + b * stride;
        const float* weights = out.coefficients.data() + b * stride;
        const int corners = out.corners[b];
        float* feature = X.col(Eigen::Index(b)).data();
        // Sums in local arrays, which for a fixed Dim the compiler keeps in vector registers;
        // only the first dim entries are used (and zeroed).
        float sum_f[kCapacity], sum_x[kCapacity], sum_y[kCapacity], sum_z[kCapacity];
        std::fill(sum_f, sum_f + dim, 0.0f);
        if (!out.eikonal[b]) {
            for (int k = 0; k < corners; ++k) {
                const T* f = table + std::size_t(rows[k]) * dim;
                const float w = weights[k];
                for (int l = 0; l < dim; ++l) sum_f[l] += w * static_cast<float>(f[l]);
            }
            std::copy(sum_f, sum_f + dim, feature);
            continue;
        }
        std::fill(sum_x, sum_x + dim, 0.0f);
        std::fill(sum_y, sum_y + dim, 0.0f);
        std::fill(sum_z, sum_z + dim, 0.0f);
        const float* dw = out.weight_gradients_per_m.data() + b * stride * 3;
        for (int k = 0; k < corners; ++k) {
            const T* f = table + std::size_t(rows[k]) * dim;
            const float w = weights[k];
            const float gx = dw[k * 3 + 0], gy = dw[k * 3 + 1], gz = dw[k * 3 + 2];
            for (int l = 0; l < dim; ++l) {
                const float fl = static_cast<float>(f[l]);
                sum_f[l] += w * fl;
                sum_x[l] += fl * gx;
                sum_y[l] += fl * gy;
                sum_z[l] += fl * gz;
            }
        }
        float* jacobian = out.jacobian.data() + b * 3 * dim;
        std::copy(sum_f, sum_f + dim, feature);
        std::copy(sum_x, sum_x + dim, jacobian);
        std::copy(sum_y, sum_y + dim, jacobian + dim);
        std::copy(sum_z, sum_z + dim, jacobian + 2 * dim);
    }
}

#if defined(SHINE_HAVE_F16C_KERNELS)
/// The 8 features of `row` of a float16 table, in float.
__attribute__((target("avx,f16c"))) inline __m256 half8_row(const Imath::half* table,
                                                            std::int32_t row) {
    return _mm256_cvtph_ps(
        _mm_loadu_si128(reinterpret_cast<const __m128i*>(table + std::size_t(row) * 8)));
}

/// gather_batch<8>() on a float16 table with AVX and F16C: a corner's 8 features are one 16-byte
/// load and one conversion instead of 8 table lookups. The same multiplications and additions in
/// the same order as the plain version (no FMA), so the same bits.
__attribute__((target("avx,f16c"))) void gather_batch_half8_f16c(BatchGradient& out,
                                                                 const Imath::half* table,
                                                                 Eigen::MatrixXf& X) {
    constexpr int kDim = 8;
    constexpr std::size_t kAhead = 2;
    const int stride = out.corner_stride;
    const std::size_t n = out.num_valid();
    for (std::size_t b = 0; b < n; ++b) {
        if (b + kAhead < n) {
            const std::int32_t* rows = out.rows.data() + (b + kAhead) * stride;
            for (int k = 0; k < out.corners[b + kAhead]; ++k) {
                __builtin_prefetch(table + std::size_t(rows[k]) * kDim);
            }
        }
        const std::int32_t* rows = out.rows.data() + b * stride;
        const float* weights = out.coefficients.data() + b * stride;
        const int corners = out.corners[b];
        float* feature = X.col(Eigen::Index(b)).data();
        __m256 sum_f = _mm256_setzero_ps();
        if (!out.eikonal[b]) {
            for (int k = 0; k < corners; ++k) {
                sum_f = _mm256_add_ps(
                    sum_f, _mm256_mul_ps(_mm256_set1_ps(weights[k]), half8_row(table, rows[k])));
            }
            _mm256_storeu_ps(feature, sum_f);
            continue;
        }
        __m256 sum_x = _mm256_setzero_ps(), sum_y = _mm256_setzero_ps(),
               sum_z = _mm256_setzero_ps();
        const float* dw = out.weight_gradients_per_m.data() + b * stride * 3;
        for (int k = 0; k < corners; ++k) {
            const __m256 f = half8_row(table, rows[k]);
            sum_f = _mm256_add_ps(sum_f, _mm256_mul_ps(_mm256_set1_ps(weights[k]), f));
            sum_x = _mm256_add_ps(sum_x, _mm256_mul_ps(f, _mm256_set1_ps(dw[k * 3 + 0])));
            sum_y = _mm256_add_ps(sum_y, _mm256_mul_ps(f, _mm256_set1_ps(dw[k * 3 + 1])));
            sum_z = _mm256_add_ps(sum_z, _mm256_mul_ps(f, _mm256_set1_ps(dw[k * 3 + 2])));
        }
        float* jacobian = out.jacobian.data() + b * 3 * kDim;
        _mm256_storeu_ps(feature, sum_f);
        _mm256_storeu_ps(jacobian, sum_x);
        _mm256_storeu_ps(jacobian + kDim, sum_y);
        _mm256_storeu_ps(jacobian + 2 * kDim, sum_z);
    }
}
#endif

template <typename T>
void gather_batch(BatchGradient& out, const T* table, int dim, Eigen::MatrixXf& X) {
#if defined(SHINE_HAVE_F16C_KERNELS)
    if constexpr (std::is_same_v<T, Imath::half>) {
        if (dim == 8 && use_avx_f16c()) return gather_batch_half8_f16c(out, table, X);
    }
#endif
    if (dim == 8) {
        gather_batch<8>(out, table, dim, X);
    } else {
        gather_batch<0>(out, table, dim, X);
    }
}

}  // namespace

void batch_loss_gradient(const NeuralSdf& sdf, CellLookup& lookup, const RaySample* samples,
                         std::size_t count, const SampleLossConfig& config, BatchGradient& out,
                         float* decoder_grads) {
    const int dim = sdf.octree.feature_dim();
    const int stride = 8 * sdf.octree.num_levels();
    const FeatureTableView features = sdf.octree.features().data();
    out.corner_stride = stride;
    out.sample.clear();
    out.corners.clear();
    out.eikonal.clear();
    out.bce_sum = out.eikonal_sum = 0.0;
    out.rows.resize(count * stride);
    out.coefficients.resize(count * stride);
    out.weight_gradients_per_m.resize(count * stride * 3);
    out.jacobian.resize(count * 3 * dim);
    out.sdf_m.resize(count);
    prepare_batch(sdf.decoder, static_cast<int>(count), out.decoder);
    Eigen::MatrixXf& X = out.decoder.features();

    // 1. Corner lookups once per sample: rows, weights (kept in coefficients until the loss
    // gradient scales them) and, for Eikonal samples, the weights' spatial gradients.
    EncodedPoint encoded;
    for (std::size_t i = 0; i < count; ++i) {
        const RaySample& sample = samples[i];
        const bool eikonal = config.eikonal_weight > 0.0f && sample.kind == SampleKind::kSurface;
        encode_point(lookup, sdf.octree, sample.point_map, eikonal, encoded);
        if (!encoded.valid()) continue;
        const std::size_t b = out.sample.size();
        out.sample.push_back(static_cast<std::uint32_t>(i));
        out.corners.push_back(static_cast<std::uint8_t>(encoded.num_corners));
        out.eikonal.push_back(eikonal ? 1 : 0);
        // A level's 8 corners at a time: fixed-size copies the compiler inlines.
        std::int32_t* rows = out.rows.data() + b * stride;
        float* weights = out.coefficients.data() + b * stride;
        for (int first = 0; first < encoded.num_corners; first += 8) {
            for (int c = first; c < first + 8; ++c) {
                rows[c] = encoded.rows[c];
                weights[c] = encoded.weights[c];
            }
        }
        if (eikonal) {
            float* dw = out.weight_gradients_per_m.data() + b * stride * 3;
            for (int k = 0; k < encoded.num_corners; ++k) {
                for (int a = 0; a < 3; ++a) dw[k * 3 + a] = encoded.weight_gradients_per_m[k][a];
            }
        }
    }
    // 2. The features F (and the Jacobian dF/dx of Eikonal samples) from the corner rows, which
    // sit at random places of the table: the rows of a sample a few ahead are prefetched.
    if (features.f16) {
        gather_batch(out, features.f16, dim, X);
    } else {
        gather_batch(out, features.f32, dim, X);
    }
    const Eigen::Index B = static_cast<Eigen::Index>(out.sample.size());
    if (B == 0) return;
    for (auto& a : out.decoder.activations) a.conservativeResize(Eigen::NoChange, B);
    out.decoder.input_gradient.resize(Eigen::NoChange, B);

    // 2. The decoder on the whole batch.
    forward_batch(sdf.decoder, out.decoder);
    input_gradient_batch(sdf.decoder, out.decoder);

    // 3. Per sample: Eq. (1) dL_bce/dtheta_c = (w_c dL/df) h; Eq. (3) for surface samples.
    const bool any_eikonal = config.eikonal_weight > 0.0f;
    out.grad_output.resize(B);
    if (decoder_grads && any_eikonal) out.grad_input_gradient.setZero(dim, B);
    const Eigen::MatrixXf& f = out.decoder.output();
    for (Eigen::Index b = 0; b < B; ++b) {
        const RaySample& sample = samples[out.sample[b]];
        const float sdf_m = f(0, b);
        out.sdf_m[b] = sdf_m;
        const LossAndGradient bce = sigmoid_bce(sdf_m, sample.sdf_label_m, config.sigma_m);
        out.bce_sum += bce.loss;
        out.grad_output[b] = bce.gradient;
        float* coefficients = out.coefficients.data() + b * stride;
        const int corners = out.corners[b];
        for (int k = 0; k < corners; ++k) coefficients[k] *= bce.gradient;
        if (!out.eikonal[b]) continue;
        const float* h = out.h(b);
        const float* jacobian = out.jacobian.data() + b * 3 * dim;  // axis-major
        float g[3] = {0.0f, 0.0f, 0.0f};
        for (int l = 0; l < dim; ++l) {
            for (int a = 0; a < 3; ++a) g[a] += jacobian[a * dim + l] * h[l];
        }
        float de_dg[3];
        out.eikonal_sum += eikonal_loss(g, de_dg);
        for (int a = 0; a < 3; ++a) de_dg[a] *= config.eikonal_weight;
        const float* dw = out.weight_gradients_per_m.data() + b * stride * 3;
        for (int k = 0; k < corners; ++k) {
            coefficients[k] +=
                dw[k * 3 + 0] * de_dg[0] + dw[k * 3 + 1] * de_dg[1] + dw[k * 3 + 2] * de_dg[2];
        }
        if (decoder_grads) {
            float* de_dh = out.grad_input_gradient.col(b).data();
            for (int l = 0; l < dim; ++l) {
                de_dh[l] = jacobian[l] * de_dg[0] + jacobian[dim + l] * de_dg[1] +
                           jacobian[2 * dim + l] * de_dg[2];
            }
        }
    }
    if (decoder_grads) {
        accumulate_param_gradient_batch(sdf.decoder, out.decoder, out.grad_output,
                                        any_eikonal ? &out.grad_input_gradient : nullptr,
                                        decoder_grads);
    }
}

}  // namespace shine
