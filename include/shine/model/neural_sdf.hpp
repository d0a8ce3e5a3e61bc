// The neural SDF: a FeatureOctree read through the shared Decoder (paper Fig. 2), in the map frame.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <utility>
#include <vector>

#include "shine/map/feature_octree.hpp"
#include "shine/model/decoder.hpp"

namespace shine {

/// Which query points count as inside the mapped region.
enum class QueryMask : std::uint8_t {
    kAnyLevel,  ///< at least one level's cell is allocated
    kLevel0,    ///< the finest level's cell is allocated (the observed region)
};

/// Feature map + decoder, with the map frame's position in the world.
struct NeuralSdf {
    FeatureOctree octree;
    Decoder decoder;
    /// World coordinates of the map frame's origin (the map frame is a translated world frame,
    /// so that far-away (e.g. UTM) coordinates keep float precision).
    Eigen::Vector3d origin_world_m = Eigen::Vector3d::Zero();

    NeuralSdf(const FeatureOctreeConfig& octree_config, const DecoderConfig& decoder_config)
        : octree(octree_config), decoder(decoder_config) {}
    NeuralSdf(FeatureOctree&& octree_in, const Decoder& decoder_in)
        : octree(std::move(octree_in)), decoder(decoder_in) {}

    /// SDF of many points (map frame), in parallel. valid[i] = 0 where the mask excludes point i
    /// (its sdf is then 0).
    void query(const std::vector<Eigen::Vector3f>& points_map, QueryMask mask,
               std::vector<float>& sdf_m, std::vector<std::uint8_t>& valid) const;

    /// A deep copy: a snapshot that registration reads while training changes this map.
    NeuralSdf clone() const {
        NeuralSdf copy(octree.clone(), decoder);
        copy.origin_world_m = origin_world_m;
        return copy;
    }

    /// Bytes of the map: features, OpenVDB structure and decoder weights.
    std::size_t memory_bytes() const {
        return octree.memory_bytes() + decoder.num_params() * sizeof(float);
    }
};

}  // namespace shine
