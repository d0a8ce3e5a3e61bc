#include "shine/model/feature_encoding.hpp"

#include <algorithm>

#include "shine/core/cpu_features.hpp"
#include "shine/map/half_convert.hpp"
#include "shine/model/interpolation.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define SHINE_HAVE_F16C_KERNELS 1
#endif

namespace shine {

namespace feature_encoding_internal {
#if defined(SHINE_HAVE_F16C_KERNELS)
/// gather_feature_and_jacobian() on a float16 table of 8 features with AVX and F16C: a corner's
/// row is one 16-byte load and one conversion, and its 8 features are summed side by side. The
/// same multiplications and additions in the same order as the plain version (no FMA), so the
/// same bits.
__attribute__((target("avx,f16c"))) void gather_feature_and_jacobian_half8(
    const EncodedPoint& encoded, const Imath::half* table, float* feature_out,
    float* jacobian_out) {
    __m256 sum_f = _mm256_setzero_ps();
    __m256 sum_x = _mm256_setzero_ps();
    __m256 sum_y = _mm256_setzero_ps();
    __m256 sum_z = _mm256_setzero_ps();
    for (int c = 0; c < encoded.num_corners; ++c) {
        const __m256 row = _mm256_cvtph_ps(_mm_loadu_si128(
            reinterpret_cast<const __m128i*>(table + std::size_t(encoded.rows[c]) * 8)));
        const float* g = encoded.weight_gradients_per_m[c];
        sum_f = _mm256_add_ps(sum_f, _mm256_mul_ps(_mm256_set1_ps(encoded.weights[c]), row));
        sum_x = _mm256_add_ps(sum_x, _mm256_mul_ps(row, _mm256_set1_ps(g[0])));
        sum_y = _mm256_add_ps(sum_y, _mm256_mul_ps(row, _mm256_set1_ps(g[1])));
        sum_z = _mm256_add_ps(sum_z, _mm256_mul_ps(row, _mm256_set1_ps(g[2])));
    }
    _mm256_storeu_ps(feature_out, sum_f);
    alignas(32) float x[8], y[8], z[8];
    _mm256_store_ps(x, sum_x);
    _mm256_store_ps(y, sum_y);
    _mm256_store_ps(z, sum_z);
    for (int l = 0; l < 8; ++l) {
        jacobian_out[l * 3 + 0] = x[l];
        jacobian_out[l * 3 + 1] = y[l];
        jacobian_out[l * 3 + 2] = z[l];
    }
}
#endif
}  // namespace feature_encoding_internal

void encode_point(CellLookup& lookup, const FeatureOctree& octree, const Eigen::Vector3f& point_map,
                  bool with_gradients, EncodedPoint& out) {
    out.num_corners = 0;
    out.has_level0 = false;
    out.level_mask = 0;
    LevelCorners cell;
    const Interpolation kind = octree.config().interpolation;
    for (int level = 0; level < octree.num_levels(); ++level) {
        if (!lookup.find_cell(level, point_map, cell)) continue;
        const int base = out.num_corners;
        for (int c = 0; c < 8; ++c) out.rows[base + c] = cell.rows[c];  // inline, not memmove
        if (with_gradients) {
            corner_weights_and_gradients(cell.t, static_cast<float>(octree.cell_size_m(level)),
                                         out.weights + base, out.weight_gradients_per_m + base,
                                         kind);
        } else {
            corner_weights(cell.t, out.weights + base, kind);
        }
        if (level == 0) out.has_level0 = true;
        out.level_mask |= 1u << level;
        out.num_corners += 8;
    }
}

namespace {

template <typename T>
void gather_feature_impl(const EncodedPoint& encoded, const T* features, int feature_dim,
                         float* feature_out) {
    std::fill(feature_out, feature_out + feature_dim, 0.0f);
    for (int c = 0; c < encoded.num_corners; ++c) {
        const T* f = features + std::size_t(encoded.rows[c]) * feature_dim;
        const float w = encoded.weights[c];
        for (int l = 0; l < feature_dim; ++l) feature_out[l] += w * static_cast<float>(f[l]);
    }
}

template <typename T>
void feature_jacobian_impl(const EncodedPoint& encoded, const T* features, int feature_dim,
                           float* jacobian_out) {
    std::fill(jacobian_out, jacobian_out + 3 * feature_dim, 0.0f);
    for (int c = 0; c < encoded.num_corners; ++c) {
        const T* f = features + std::size_t(encoded.rows[c]) * feature_dim;
        const float* g = encoded.weight_gradients_per_m[c];
        for (int l = 0; l < feature_dim; ++l) {
            const float fl = static_cast<float>(f[l]);
            jacobian_out[l * 3 + 0] += fl * g[0];
            jacobian_out[l * 3 + 1] += fl * g[1];
            jacobian_out[l * 3 + 2] += fl * g[2];
        }
    }
}

}  // namespace

void gather_feature(const EncodedPoint& encoded, FeatureTableView features, int feature_dim,
                    float* feature_out) {
    if (features.f16) {
        gather_feature_impl(encoded, features.f16, feature_dim, feature_out);
    } else {
        gather_feature_impl(encoded, features.f32, feature_dim, feature_out);
    }
}

void gather_feature_and_jacobian(const EncodedPoint& encoded, FeatureTableView features,
                                 int feature_dim, float* feature_out, float* jacobian_out) {
#if defined(SHINE_HAVE_F16C_KERNELS)
    if (features.f16 && feature_dim == 8 && use_avx_f16c()) {
        return feature_encoding_internal::gather_feature_and_jacobian_half8(
            encoded, features.f16, feature_out, jacobian_out);
    }
#endif
    std::fill(feature_out, feature_out + feature_dim, 0.0f);
    std::fill(jacobian_out, jacobian_out + 3 * feature_dim, 0.0f);
    float row[kMaxFeatureDim];
    for (int c = 0; c < encoded.num_corners; ++c) {
        const std::size_t first = std::size_t(encoded.rows[c]) * feature_dim;
        if (features.f16) {
            halves_to_floats(features.f16 + first, row, static_cast<std::size_t>(feature_dim));
        } else {
            std::copy(features.f32 + first, features.f32 + first + feature_dim, row);
        }
        const float w = encoded.weights[c];
        const float* g = encoded.weight_gradients_per_m[c];
        for (int l = 0; l < feature_dim; ++l) {
            feature_out[l] += w * row[l];
            jacobian_out[l * 3 + 0] += row[l] * g[0];
            jacobian_out[l * 3 + 1] += row[l] * g[1];
            jacobian_out[l * 3 + 2] += row[l] * g[2];
        }
    }
}

void feature_jacobian(const EncodedPoint& encoded, FeatureTableView features, int feature_dim,
                      float* jacobian_out) {
    if (features.f16) {
        feature_jacobian_impl(encoded, features.f16, feature_dim, jacobian_out);
    } else {
        feature_jacobian_impl(encoded, features.f32, feature_dim, jacobian_out);
    }
}

}  // namespace shine
