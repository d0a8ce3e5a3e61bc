#include "shine/model/neural_sdf.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "shine/model/feature_encoding.hpp"

namespace shine {

void NeuralSdf::query(const std::vector<Eigen::Vector3f>& points_map, QueryMask mask,
                      std::vector<float>& sdf_m, std::vector<std::uint8_t>& valid) const {
    sdf_m.assign(points_map.size(), 0.0f);
    valid.assign(points_map.size(), 0);
    const int dim = octree.feature_dim();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points_map.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          CellLookup lookup(octree);
                          DecoderLanes lanes(decoder);
                          std::size_t lane_point[kDecoderLanes];
                          EncodedPoint encoded;
                          float feature[kMaxFeatureDim];
                          const auto emit = [&] {
                              const int n = lanes.size();
                              const float* f = lanes.evaluate();
                              for (int s = 0; s < n; ++s) sdf_m[lane_point[s]] = f[s];
                          };
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              encode_point(lookup, octree, points_map[i], false, encoded);
                              const bool ok =
                                  mask == QueryMask::kLevel0 ? encoded.has_level0 : encoded.valid();
                              if (!ok) continue;
                              gather_feature(encoded, octree.features().data(), dim, feature);
                              lane_point[lanes.size()] = i;
                              lanes.add(feature);
                              if (lanes.full()) emit();
                              valid[i] = 1;
                          }
                          emit();
                      });
}

}  // namespace shine
