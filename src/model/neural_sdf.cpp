#include "shine/model/neural_sdf.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "shine/model/decoder_lanes.hpp"
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
                          DecoderLaneQueue<std::size_t> lanes(decoder);
                          EncodedPoint encoded;
                          float feature[kMaxFeatureDim];
                          const auto emit = [&](std::size_t point, float f) { sdf_m[point] = f; };
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              encode_point(lookup, octree, points_map[i], false, encoded);
                              const bool ok =
                                  mask == QueryMask::kLevel0 ? encoded.has_level0 : encoded.valid();
                              if (!ok) continue;
                              gather_feature(encoded, octree.features().data(), dim, feature);
                              lanes.add(feature, i, emit);
                              valid[i] = 1;
                          }
                          lanes.flush(emit);
                      });
}

}  // namespace shine
