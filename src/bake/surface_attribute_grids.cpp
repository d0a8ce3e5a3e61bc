#include "shine/bake/surface_attribute_grids.hpp"

#include <openvdb/io/File.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"

namespace shine {
namespace surface_attribute_grids_internal {
namespace {

template <typename GridT>
typename GridT::Ptr empty_grid_like(const openvdb::FloatGrid& level_set, const char* name) {
    auto grid = GridT::create(typename GridT::ValueType(0));
    grid->setTransform(level_set.transform().copy());
    for (auto it = level_set.beginMeta(); it != level_set.endMeta(); ++it) {
        grid->insertMeta(it->first, *it->second);  // origin, creator, ...
    }
    grid->setName(name);
    grid->setGridClass(openvdb::GRID_UNKNOWN);
    return grid;
}

void check_sizes(std::size_t vertices, std::size_t values, const char* what) {
    if (vertices != values) {
        throw DataError(std::string(what) + ": " + std::to_string(values) + " values for " +
                        std::to_string(vertices) + " vertices");
    }
}

/// Per vertex with `known(v)`, `value_of(v)` (a Vec4f: the value's channels and a count of 1 in
/// w) summed into every active level-set voxel at a corner of the vertex's cell, and each such
/// voxel's `mean_of(sum)` (GridT's value) written to `grid`.
///
/// Parallel over the output's leaf nodes: every vertex is listed under the leaves its cell's
/// corners fall in, the lists sorted by leaf and then vertex, and each leaf sums its vertices in
/// vertex order, as one pass over the vertices in order would: the sums are the same bits
/// whatever the thread count.
template <typename GridT, typename ValueOf, typename Known, typename MeanOf>
void fill_corner_means(GridT& grid, const openvdb::FloatGrid& level_set,
                       const std::vector<Eigen::Vector3f>& vertices_map, ValueOf value_of,
                       Known known, MeanOf mean_of) {
    using LeafT = typename GridT::TreeType::LeafNodeType;
    constexpr int kDim = static_cast<int>(LeafT::DIM);  // 8
    const openvdb::math::Transform& xform = level_set.transform();
    const auto cell_of = [&](std::size_t v) {
        const Eigen::Vector3f& p = vertices_map[v];
        return openvdb::Coord::floor(xform.worldToIndex(openvdb::Vec3d(p.x(), p.y(), p.z())));
    };
    struct Record {
        openvdb::Coord leaf;  ///< the leaf node's origin
        std::uint32_t vertex;
        bool operator<(const Record& o) const {
            return leaf != o.leaf ? leaf < o.leaf : vertex < o.vertex;
        }
    };
    // Each vertex under the leaves its cell's corners reach (1 to 8: a cell on a leaf's far face
    // reaches into the next leaf), listed in blocks of vertices in parallel.
    constexpr std::size_t kBlock = 16384;
    const std::size_t blocks = (vertices_map.size() + kBlock - 1) / kBlock;
    std::vector<std::vector<Record>> block_records(blocks);
    tbb::parallel_for(std::size_t(0), blocks, [&](std::size_t b) {
        const std::size_t end = std::min(vertices_map.size(), (b + 1) * kBlock);
        for (std::size_t v = b * kBlock; v < end; ++v) {
            if (!known(v)) continue;
            const openvdb::Coord base = cell_of(v);
            const openvdb::Coord first = base & ~(kDim - 1);
            const openvdb::Coord last = base.offsetBy(1) & ~(kDim - 1);
            for (int x = first.x(); x <= last.x(); x += kDim) {
                for (int y = first.y(); y <= last.y(); y += kDim) {
                    for (int z = first.z(); z <= last.z(); z += kDim) {
                        block_records[b].push_back(
                            {openvdb::Coord(x, y, z), static_cast<std::uint32_t>(v)});
                    }
                }
            }
        }
    });
    std::vector<Record> records;
    for (const auto& block : block_records)
        records.insert(records.end(), block.begin(), block.end());
    block_records = {};
    tbb::parallel_sort(records.begin(), records.end());
    std::vector<std::size_t> starts;
    for (std::size_t i = 0; i < records.size(); ++i) {
        if (i == 0 || records[i].leaf != records[i - 1].leaf) starts.push_back(i);
    }
    starts.push_back(records.size());
    std::vector<std::unique_ptr<LeafT>> leaves(starts.size() - 1);
    tbb::parallel_for(std::size_t(0), leaves.size(), [&](std::size_t g) {
        const openvdb::Coord origin = records[starts[g]].leaf;
        auto level = level_set.getConstAccessor();
        std::array<openvdb::Vec4f, LeafT::SIZE> sums;
        sums.fill(openvdb::Vec4f(0.0f));
        for (std::size_t i = starts[g]; i < starts[g + 1]; ++i) {
            const std::size_t v = records[i].vertex;
            const openvdb::Coord base = cell_of(v);
            const openvdb::Vec4f value = value_of(v);
            for (int corner = 0; corner < 8; ++corner) {
                const openvdb::Coord ijk =
                    base.offsetBy(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
                if ((ijk & ~(kDim - 1)) != origin || !level.isValueOn(ijk)) continue;
                openvdb::Vec4f& sum = sums[LeafT::coordToOffset(ijk)];
                sum = sum + value;
            }
        }
        auto leaf = std::make_unique<LeafT>(origin, typename GridT::ValueType(0), false);
        bool any = false;
        for (openvdb::Index n = 0; n < LeafT::SIZE; ++n) {
            if (sums[n][3] == 0.0f) continue;
            leaf->setValueOn(n, mean_of(sums[n]));
            any = true;
        }
        if (any) leaves[g] = std::move(leaf);
    });
    for (auto& leaf : leaves) {
        if (leaf) grid.tree().addLeaf(leaf.release());
    }
}

}  // namespace
}  // namespace surface_attribute_grids_internal

openvdb::Vec3SGrid::Ptr color_grid_from_vertices(
    const openvdb::FloatGrid& level_set, const std::vector<Eigen::Vector3f>& vertices_map,
    const std::vector<std::array<std::uint8_t, 3>>& rgb, const std::vector<std::uint8_t>& known) {
    using namespace surface_attribute_grids_internal;
    check_sizes(vertices_map.size(), rgb.size(), "color grid");
    check_sizes(vertices_map.size(), known.size(), "color grid's known flags");
    auto grid = empty_grid_like<openvdb::Vec3SGrid>(level_set, kColorGridName);
    grid->setVectorType(openvdb::VEC_INVARIANT);
    fill_corner_means(
        *grid, level_set, vertices_map,
        [&](std::size_t v) {
            return openvdb::Vec4f(rgb[v][0] / 255.0f, rgb[v][1] / 255.0f, rgb[v][2] / 255.0f, 1.0f);
        },
        [&](std::size_t v) { return known[v] != 0; },
        [](const openvdb::Vec4f& s) {
            return openvdb::Vec3s(s[0] / s[3], s[1] / s[3], s[2] / s[3]);
        });
    return grid;
}

openvdb::FloatGrid::Ptr intensity_grid_from_vertices(
    const openvdb::FloatGrid& level_set, const std::vector<Eigen::Vector3f>& vertices_map,
    const std::vector<float>& intensity) {
    using namespace surface_attribute_grids_internal;
    check_sizes(vertices_map.size(), intensity.size(), "intensity grid");
    auto grid = empty_grid_like<openvdb::FloatGrid>(level_set, kIntensityGridName);
    fill_corner_means(
        *grid, level_set, vertices_map,
        [&](std::size_t v) { return openvdb::Vec4f(intensity[v], 0.0f, 0.0f, 1.0f); },
        [&](std::size_t v) { return std::isfinite(intensity[v]); },
        [](const openvdb::Vec4f& s) { return s[0] / s[3]; });
    return grid;
}

void write_surface_grids(const std::filesystem::path& path,
                         const openvdb::FloatGrid::Ptr& level_set,
                         const openvdb::GridPtrVec& extra) {
    openvdb::initialize();
    openvdb::GridPtrVec grids{level_set};
    grids.insert(grids.end(), extra.begin(), extra.end());
    write_file_atomically(path, [&](const std::filesystem::path& tmp) {
        try {
            openvdb::io::File file(tmp.string());
            file.write(grids);
            file.close();
        } catch (const openvdb::Exception& e) {
            throw IoError("cannot write '" + path.string() + "': " + e.what());
        }
    });
}

}  // namespace shine
