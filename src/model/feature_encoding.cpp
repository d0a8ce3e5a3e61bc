#include "shine/model/feature_encoding.hpp"

#include <algorithm>

#include "shine/map/half_convert.hpp"
#include "shine/model/interpolation.hpp"

namespace shine {

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
