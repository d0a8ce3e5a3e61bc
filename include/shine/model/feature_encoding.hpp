// The hierarchical feature of a query point: per level, interpolate the 8 corner features of the
// cell containing it; sum over levels (paper Fig. 2). Also the Jacobian dF/dx needed by the
// Eikonal term, and the scatter of dL/dF back onto the corner features.
#pragma once

#include <Eigen/Core>
#include <cstdint>

#include "shine/map/feature_octree.hpp"

namespace shine {

/// Maximum levels supported by the fixed-size encoding record.
constexpr int kMaxLevels = 8;
/// Maximum feature length supported by the fixed-size buffers of the kernels.
constexpr int kMaxFeatureDim = 64;

/// The corners one query point reads: for each contributing level, 8 rows with their weights and
/// weight gradients (per metre). Levels whose cell is not allocated do not contribute.
struct EncodedPoint {
    int num_corners = 0;  ///< 8 x number of contributing levels
    std::int32_t rows[8 * kMaxLevels];
    float weights[8 * kMaxLevels];
    float weight_gradients_per_m[8 * kMaxLevels][3];
    bool has_level0 = false;       ///< the finest level contributes
    std::uint32_t level_mask = 0;  ///< bit l set when level l contributes

    bool valid() const { return num_corners > 0; }
};

/// Looks up the corners of `point_map` on every level. With `with_gradients` false the weight
/// gradients are left unset (saves work when only the SDF value is needed).
void encode_point(CellLookup& lookup, const FeatureOctree& octree, const Eigen::Vector3f& point_map,
                  bool with_gradients, EncodedPoint& out);

/// F = sum over corners of weight * feature (length feature_dim), in float whatever the table's
/// precision (`features` is FeatureTable::data()).
void gather_feature(const EncodedPoint& encoded, FeatureTableView features, int feature_dim,
                    float* feature_out);

/// J = dF/dx, feature_dim x 3, row-major: J[l*3 + a] = sum_c feature_c[l] * dw_c/dx_a.
void feature_jacobian(const EncodedPoint& encoded, FeatureTableView features, int feature_dim,
                      float* jacobian_out);

/// gather_feature() and feature_jacobian() together, each corner's row read (and, in a float16
/// table, converted) once: the same sums in the same order, so the same bits as the two calls.
void gather_feature_and_jacobian(const EncodedPoint& encoded, FeatureTableView features,
                                 int feature_dim, float* feature_out, float* jacobian_out);

}  // namespace shine
