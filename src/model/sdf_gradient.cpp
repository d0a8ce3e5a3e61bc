// SDF value and spatial gradient grad f = J^T h of a NeuralSdf.
#include "shine/model/sdf_gradient.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>

#include "shine/model/feature_encoding.hpp"
#include "shine/model/interpolation.hpp"

namespace shine {

namespace sdf_gradient_internal {

/// encode_point() with gradients, each level's cell taken from `remembered` (num_levels entries)
/// when the point still lies in it, else looked up and remembered. The cell's base and the
/// point's place in it are computed as CellLookup::find_cell computes them (p * (1 / cell size)
/// in double, floored), so the weights are the same bits.
void encode_point_remembered(CellLookup& lookup, const FeatureOctree& octree,
                             const double* inverse_cell_size, const Eigen::Vector3f& point_map,
                             QueryCellMemory::Cell* remembered, EncodedPoint& out) {
    out.num_corners = 0;
    out.has_level0 = false;
    out.level_mask = 0;
    const Interpolation kind = octree.config().interpolation;
    for (int level = 0; level < octree.num_levels(); ++level) {
        const double inv = inverse_cell_size[level];
        const double g[3] = {point_map.x() * inv, point_map.y() * inv, point_map.z() * inv};
        std::int64_t base[3];
        float t[3];
        for (int a = 0; a < 3; ++a) {
            const double f = std::floor(g[a]);
            base[a] = static_cast<std::int64_t>(f);
            t[a] = static_cast<float>(g[a] - f);
        }
        QueryCellMemory::Cell& cell = remembered[level];
        if (!cell.known || cell.base[0] != base[0] || cell.base[1] != base[1] ||
            cell.base[2] != base[2]) {
            LevelCorners corners;
            cell.found = lookup.find_cell(level, point_map, corners);
            for (int c = 0; c < 8; ++c) cell.rows[c] = corners.rows[c];
            for (int a = 0; a < 3; ++a) cell.base[a] = base[a];
            cell.known = true;
        }
        if (!cell.found) continue;
        const int base_corner = out.num_corners;
        for (int c = 0; c < 8; ++c) out.rows[base_corner + c] = cell.rows[c];
        corner_weights_and_gradients(t, static_cast<float>(octree.cell_size_m(level)),
                                     out.weights + base_corner,
                                     out.weight_gradients_per_m + base_corner, kind);
        if (level == 0) out.has_level0 = true;
        out.level_mask |= 1u << level;
        out.num_corners += 8;
    }
}

}  // namespace sdf_gradient_internal

void query_sdf_and_gradient(const NeuralSdf& sdf, const std::vector<Eigen::Vector3f>& points_map,
                            QueryMask mask, std::vector<float>& sdf_m,
                            std::vector<Eigen::Vector3f>& gradient_map,
                            std::vector<std::uint8_t>& valid, QueryCellMemory* memory) {
    const std::size_t n = points_map.size();
    const int levels = sdf.octree.num_levels();
    double inverse_cell_size[kMaxLevels] = {};
    if (memory) {
        if (memory->cells.size() != n * static_cast<std::size_t>(levels)) {
            memory->cells.assign(n * static_cast<std::size_t>(levels), QueryCellMemory::Cell{});
        }
        // As CellLookup's: 1 / cell_size_m(level).
        for (int l = 0; l < levels && l < kMaxLevels; ++l) {
            inverse_cell_size[l] = 1.0 / sdf.octree.cell_size_m(l);
        }
    }
    sdf_m.assign(n, 0.0f);
    gradient_map.assign(n, Eigen::Vector3f::Zero());
    valid.assign(n, 0);
    const int dim = sdf.octree.feature_dim();
    const FeatureTableView features = sdf.octree.features().data();
    constexpr int S = kDecoderLanes;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 512),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          CellLookup lookup(sdf.octree);
                          DecoderWorkspace ws;
                          sdf.decoder.prepare(ws);
                          // Up to kDecoderLanes points are evaluated together
                          // (Decoder::forward_lanes and input_gradient_lanes, forward's and
                          // input_gradient's values bit for bit).
                          EncodedPoint encoded[S];
                          std::size_t index[S];
                          int count = 0;
                          float lane_features[kMaxFeatureDim * S];
                          float lane_h[kMaxFeatureDim * S];
                          float f[S];
                          float feature[kMaxFeatureDim];
                          float jacobian[S][3 * kMaxFeatureDim];
                          const auto flush = [&] {
                              for (int s = count; s < S; ++s) {
                                  for (int l = 0; l < dim; ++l) lane_features[l * S + s] = 0.0f;
                              }
                              sdf.decoder.forward_lanes(lane_features, f, ws);
                              sdf.decoder.input_gradient_lanes(ws, lane_h);
                              for (int s = 0; s < count; ++s) {
                                  const std::size_t i = index[s];
                                  sdf_m[i] = f[s];
                                  Eigen::Vector3f g = Eigen::Vector3f::Zero();
                                  for (int l = 0; l < dim; ++l) {
                                      for (int a = 0; a < 3; ++a) {
                                          g[a] += jacobian[s][l * 3 + a] * lane_h[l * S + s];
                                      }
                                  }
                                  gradient_map[i] = g;
                                  valid[i] = 1;
                              }
                              count = 0;
                          };
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              EncodedPoint& e = encoded[count];
                              if (memory) {
                                  sdf_gradient_internal::encode_point_remembered(
                                      lookup, sdf.octree, inverse_cell_size, points_map[i],
                                      &memory->cells[i * static_cast<std::size_t>(levels)], e);
                              } else {
                                  encode_point(lookup, sdf.octree, points_map[i], true, e);
                              }
                              const bool ok = mask == QueryMask::kLevel0 ? e.has_level0 : e.valid();
                              if (!ok) continue;
                              gather_feature_and_jacobian(e, features, dim, feature,
                                                          jacobian[count]);
                              for (int l = 0; l < dim; ++l)
                                  lane_features[l * S + count] = feature[l];
                              index[count++] = i;
                              if (count == S) flush();
                          }
                          if (count > 0) flush();
                      });
}

}  // namespace shine
