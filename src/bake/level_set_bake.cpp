#include "shine/bake/level_set_bake.hpp"

#include <openvdb/tools/SignedFloodFill.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

#include "shine/core/error.hpp"
#include "shine/model/decoder_lanes.hpp"
#include "shine/model/feature_encoding.hpp"

namespace shine {

double resolve_bake_voxel_size_m(const BakeConfig& config, double leaf_size_m) {
    return config.voxel_size_m > 0.0 ? config.voxel_size_m : 0.5 * leaf_size_m;
}

openvdb::FloatGrid::Ptr bake_level_set(const NeuralSdf& sdf, const BakeConfig& config,
                                       BakeStats* stats) {
    openvdb::initialize();
    const double voxel_m = resolve_bake_voxel_size_m(config, sdf.octree.config().leaf_size_m);
    if (!(voxel_m > 0.0) || !std::isfinite(voxel_m)) {
        throw ConfigError("bake voxel_size_m must be positive, got " + std::to_string(voxel_m));
    }
    if (!(config.half_width_voxels >= 1.0f)) {
        throw ConfigError("bake half_width_voxels must be at least 1");
    }
    const float background_m = static_cast<float>(config.half_width_voxels * voxel_m);
    if (config.mask_level < 0 || config.mask_level >= sdf.octree.num_levels()) {
        throw ConfigError("bake mask_level must be between 0 and " +
                          std::to_string(sdf.octree.num_levels() - 1));
    }
    const double leaf_m = sdf.octree.cell_size_m(config.mask_level);
    const std::uint32_t mask_bit = 1u << config.mask_level;
    const std::vector<Eigen::Vector3i> cells = sdf.octree.cells(config.mask_level);

    auto grid = openvdb::FloatGrid::create(background_m);
    // The grid stays in the map frame (index * voxel_m); the map frame's world position is the
    // shine_origin_world_m metadata below. A world-frame transform would put far-away (UTM) maps
    // at 5e6 m, where the float32 coordinates of meshers, Blender and Houdini are 0.5 m apart.
    grid->setTransform(openvdb::math::Transform::createLinearTransform(voxel_m));
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    grid->setName("surface");
    std::size_t evaluated = 0;
    openvdb::MaskGrid evaluated_mask;

    // Per block of cells, evaluate the voxels whose sample point lies inside the cell: voxel
    // indices i with cell*leaf <= i*voxel < (cell+1)*leaf, so every voxel belongs to one cell.
    // The blocks are evaluated in parallel a region at a time (kBlocksPerRegion blocks of cells,
    // consecutive in the octree's spatial order) and each region's values go into the grid before
    // the next is evaluated: the evaluated values of the whole map are never held at once, so
    // the bake of a long drive needs the grid's memory, not a copy of every sample on top.
    struct Value {
        openvdb::Coord ijk;
        float sdf_m;
    };
    constexpr std::size_t kBlock = 256;
    constexpr std::size_t kBlocksPerRegion = 512;
    const std::size_t num_blocks = (cells.size() + kBlock - 1) / kBlock;
    const int dim = sdf.octree.feature_dim();
    std::vector<std::vector<Value>> block_values;
    auto accessor = grid->getAccessor();
    auto mask = evaluated_mask.getAccessor();
    for (std::size_t first_block = 0; first_block < num_blocks; first_block += kBlocksPerRegion) {
        const std::size_t region_blocks = std::min(kBlocksPerRegion, num_blocks - first_block);
        block_values.assign(region_blocks, {});
        tbb::parallel_for(std::size_t(0), region_blocks, [&](std::size_t b) {
            const std::size_t block = first_block + b;
            CellLookup lookup(sdf.octree);
            DecoderLaneQueue<openvdb::Coord> lanes(sdf.decoder);
            EncodedPoint encoded;
            float feature[kMaxFeatureDim];
            auto& values = block_values[b];
            const auto emit = [&](const openvdb::Coord& ijk, float sdf_m) {
                values.push_back({ijk, sdf_m});
            };
            const std::size_t end = std::min(cells.size(), (block + 1) * kBlock);
            for (std::size_t c = block * kBlock; c < end; ++c) {
                int lo[3], hi[3];
                for (int a = 0; a < 3; ++a) {
                    lo[a] = static_cast<int>(std::ceil(cells[c][a] * leaf_m / voxel_m - 1e-9));
                    hi[a] =
                        static_cast<int>(std::ceil((cells[c][a] + 1) * leaf_m / voxel_m - 1e-9));
                }
                for (int i = lo[0]; i < hi[0]; ++i) {
                    for (int j = lo[1]; j < hi[1]; ++j) {
                        for (int k = lo[2]; k < hi[2]; ++k) {
                            const Eigen::Vector3f p(static_cast<float>(i * voxel_m),
                                                    static_cast<float>(j * voxel_m),
                                                    static_cast<float>(k * voxel_m));
                            encode_point(lookup, sdf.octree, p, false, encoded);
                            if (!(encoded.level_mask & mask_bit)) continue;
                            gather_feature(encoded, sdf.octree.features().data(), dim, feature);
                            lanes.add(feature, openvdb::Coord(i, j, k), emit);
                        }
                    }
                }
            }
            lanes.flush(emit);
        });
        for (const auto& values : block_values) {
            evaluated += values.size();
            for (const auto& v : values) {
                mask.setValueOn(v.ijk);
                if (std::abs(v.sdf_m) < background_m) {
                    accessor.setValueOn(v.ijk, v.sdf_m);
                } else {
                    accessor.setValueOff(v.ijk, v.sdf_m > 0.0f ? background_m : -background_m);
                }
            }
        }
    }
    block_values.clear();
    block_values.shrink_to_fit();
    openvdb::tools::signedFloodFill(grid->tree());
    // Mesh extraction (OpenVDB's and Blender's) makes a polygon wherever an active voxel and a
    // neighbour differ in sign. Outside the evaluated region the flood fill's sign is a guess, and
    // a wrong guess next to the band (e.g. below an observed ground strip) would add a false
    // surface. So every unevaluated neighbour of the band takes the sign its band neighbours
    // agree on (the sum of their values): only where the surface itself leaves the observed
    // region does a crossing remain, a skirt of at most one voxel. The sum is gathered at the
    // unevaluated voxel from its active neighbours, whose values this pass never changes, so no
    // list of a city's band boundary is held; the leaves are listed first because setting a value
    // may add leaves.
    {
        using LeafT = openvdb::FloatTree::LeafNodeType;
        std::vector<const LeafT*> band_leaves;
        for (auto leaf = grid->tree().cbeginLeaf(); leaf; ++leaf) {
            if (!leaf->isEmpty()) band_leaves.push_back(leaf.getLeaf());
        }
        auto done = evaluated_mask.getConstAccessor();
        auto band = grid->getConstAccessor();
        for (const LeafT* leaf : band_leaves) {
            for (auto voxel = leaf->cbeginValueOn(); voxel; ++voxel) {
                for (int axis = 0; axis < 3; ++axis) {
                    for (int step : {-1, 1}) {
                        openvdb::Coord n = voxel.getCoord();
                        n[axis] += step;
                        if (done.isValueOn(n)) continue;
                        float sum = 0.0f;
                        for (int a = 0; a < 3; ++a) {
                            for (int s : {-1, 1}) {
                                openvdb::Coord m = n;
                                m[a] += s;
                                float value;
                                if (band.probeValue(m, value)) sum += value;
                            }
                        }
                        accessor.setValueOff(n, sum < 0.0f ? -background_m : background_m);
                    }
                }
            }
        }
    }
    grid->tree().prune();
    grid->insertMeta("shine_origin_world_m",
                     openvdb::Vec3DMetadata(openvdb::Vec3d(
                         sdf.origin_world_m.x(), sdf.origin_world_m.y(), sdf.origin_world_m.z())));
    if (stats) {
        stats->evaluated_voxels = evaluated;
        stats->active_voxels = grid->activeVoxelCount();
        stats->voxel_size_m = voxel_m;
    }
    return grid;
}

}  // namespace shine
