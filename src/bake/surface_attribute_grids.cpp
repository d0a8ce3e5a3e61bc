#include "shine/bake/surface_attribute_grids.hpp"

#include <openvdb/io/File.h>

#include <cmath>
#include <string>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"

namespace shine {
namespace surface_attribute_grids_internal {
namespace {

/// In-memory sums (value channels, count in w); never written, so never registered.
using Vec4fGrid = openvdb::Grid<openvdb::tree::Tree4<openvdb::Vec4f, 5, 4, 3>::Type>;

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

/// Sums `value(v)` (a Vec4f: the value's channels and a count of 1 in w) over the vertices
/// with `known(v)`, into every active level-set voxel at a corner of the vertex's cell.
template <typename ValueOf, typename Known>
Vec4fGrid::Ptr corner_sums(const openvdb::FloatGrid& level_set,
                           const std::vector<Eigen::Vector3f>& vertices_map, ValueOf value_of,
                           Known known) {
    auto sums = Vec4fGrid::create(openvdb::Vec4f(0.0f));
    auto sum_at = sums->getAccessor();
    auto level = level_set.getConstAccessor();
    const openvdb::math::Transform& xform = level_set.transform();
    for (std::size_t v = 0; v < vertices_map.size(); ++v) {
        if (!known(v)) continue;
        const Eigen::Vector3f& p = vertices_map[v];
        const openvdb::Vec3d index = xform.worldToIndex(openvdb::Vec3d(p.x(), p.y(), p.z()));
        const openvdb::Coord base = openvdb::Coord::floor(index);
        const openvdb::Vec4f value = value_of(v);
        for (int corner = 0; corner < 8; ++corner) {
            const openvdb::Coord ijk =
                base.offsetBy(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
            if (!level.isValueOn(ijk)) continue;
            sum_at.setValue(ijk, sum_at.getValue(ijk) + value);
        }
    }
    return sums;
}

}  // namespace
}  // namespace surface_attribute_grids_internal

openvdb::Vec3SGrid::Ptr color_grid_from_vertices(
    const openvdb::FloatGrid& level_set, const std::vector<Eigen::Vector3f>& vertices_map,
    const std::vector<std::array<std::uint8_t, 3>>& rgb, const std::vector<std::uint8_t>& known) {
    using namespace surface_attribute_grids_internal;
    check_sizes(vertices_map.size(), rgb.size(), "color grid");
    check_sizes(vertices_map.size(), known.size(), "color grid's known flags");
    const auto sums = corner_sums(
        level_set, vertices_map,
        [&](std::size_t v) {
            return openvdb::Vec4f(rgb[v][0] / 255.0f, rgb[v][1] / 255.0f, rgb[v][2] / 255.0f, 1.0f);
        },
        [&](std::size_t v) { return known[v] != 0; });
    auto grid = empty_grid_like<openvdb::Vec3SGrid>(level_set, kColorGridName);
    grid->setVectorType(openvdb::VEC_INVARIANT);
    auto out = grid->getAccessor();
    for (auto it = sums->cbeginValueOn(); it; ++it) {
        const openvdb::Vec4f s = *it;
        out.setValue(it.getCoord(), openvdb::Vec3s(s[0] / s[3], s[1] / s[3], s[2] / s[3]));
    }
    return grid;
}

openvdb::FloatGrid::Ptr intensity_grid_from_vertices(
    const openvdb::FloatGrid& level_set, const std::vector<Eigen::Vector3f>& vertices_map,
    const std::vector<float>& intensity) {
    using namespace surface_attribute_grids_internal;
    check_sizes(vertices_map.size(), intensity.size(), "intensity grid");
    const auto sums = corner_sums(
        level_set, vertices_map,
        [&](std::size_t v) { return openvdb::Vec4f(intensity[v], 0.0f, 0.0f, 1.0f); },
        [&](std::size_t v) { return std::isfinite(intensity[v]); });
    auto grid = empty_grid_like<openvdb::FloatGrid>(level_set, kIntensityGridName);
    auto out = grid->getAccessor();
    for (auto it = sums->cbeginValueOn(); it; ++it) {
        const openvdb::Vec4f s = *it;
        out.setValue(it.getCoord(), s[0] / s[3]);
    }
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
