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
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 512),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          CellLookup lookup(sdf.octree);
                          DecoderWorkspace ws;
                          sdf.decoder.prepare(ws);
                          EncodedPoint encoded;
                          float feature[kMaxFeatureDim];
                          float h[kMaxFeatureDim];
                          float jacobian[3 * kMaxFeatureDim];
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              encode_point(lookup, sdf.octree, points_map[i], true, encoded);
                              const bool ok =
                                  mask == QueryMask::kLevel0 ? encoded.has_level0 : encoded.valid();
                              if (!ok) continue;
                              gather_feature(encoded, features, dim, feature);
                              sdf_m[i] = sdf.decoder.forward(feature, ws);
                              sdf.decoder.input_gradient(ws, h);
                              feature_jacobian(encoded, features, dim, jacobian);
                              Eigen::Vector3f g = Eigen::Vector3f::Zero();
                              for (int l = 0; l < dim; ++l) {
                                  for (int a = 0; a < 3; ++a) g[a] += jacobian[l * 3 + a] * h[l];
                              }
                              gradient_map[i] = g;
                              valid[i] = 1;
                          }
                      });
}

}  // namespace shine
