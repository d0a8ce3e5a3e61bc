// SDF value and spatial gradient grad f = J^T h of a NeuralSdf.
#include "shine/model/sdf_gradient.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "shine/model/feature_encoding.hpp"

namespace shine {

void query_sdf_and_gradient(const NeuralSdf& sdf, const std::vector<Eigen::Vector3f>& points_map,
                            QueryMask mask, std::vector<float>& sdf_m,
                            std::vector<Eigen::Vector3f>& gradient_map,
                            std::vector<std::uint8_t>& valid) {
    const std::size_t n = points_map.size();
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
                              encode_point(lookup, sdf.octree, points_map[i], true, e);
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
