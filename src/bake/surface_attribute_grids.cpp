#include "shine/bake/surface_attribute_grids.hpp"

#include <openvdb/io/File.h>
#include <openvdb/tools/Interpolation.h>

#include <cmath>
#include <string>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"

namespace shine {

LevelSetSurfacePoints level_set_surface_points(const openvdb::FloatGrid& level_set) {
    LevelSetSurfacePoints out;
    const openvdb::math::Transform& xform = level_set.transform();
    const double voxel_m = xform.voxelSize()[0];
    auto accessor = level_set.getConstAccessor();
    for (auto it = level_set.cbeginValueOn(); it; ++it) {
        const openvdb::Coord ijk = it.getCoord();
        const double phi = *it;
        Eigen::Vector3d gradient;
        for (int a = 0; a < 3; ++a) {
            openvdb::Coord lo = ijk, hi = ijk;
            lo[a] -= 1;
            hi[a] += 1;
            gradient[a] = (accessor.getValue(hi) - accessor.getValue(lo)) / (2.0 * voxel_m);
        }
        const openvdb::Vec3d centre = xform.indexToWorld(ijk);
        Eigen::Vector3d point(centre.x(), centre.y(), centre.z());
        const double g2 = gradient.squaredNorm();
        Eigen::Vector3d normal = Eigen::Vector3d::Zero();
        if (g2 > 1e-12) {
            normal = gradient / std::sqrt(g2);
            // Never farther than the band's half-width: a gradient near a seam may be small.
            const Eigen::Vector3d step = phi * gradient / g2;
            const double limit_m = 3.0 * voxel_m;
            point -= step.norm() > limit_m ? step * (limit_m / step.norm()) : step;
            // A second step along the normal with the distance sampled where the first one
            // landed: at the band's edge the central differences see the clamped background.
            const openvdb::Vec3d index =
                xform.worldToIndex(openvdb::Vec3d(point.x(), point.y(), point.z()));
            const double residual_m = openvdb::tools::BoxSampler::sample(accessor, index);
            if (std::abs(residual_m) < limit_m) point -= residual_m * normal;
        }
        out.voxels.push_back(ijk);
        out.points_map.push_back(point);
        out.normals_map.push_back(normal);
    }
    return out;
}

namespace {
template <typename GridT>
typename GridT::Ptr empty_grid_like(const openvdb::FloatGrid& level_set, const char* name) {
    auto grid = GridT::create(typename GridT::ValueType(0));
    grid->setTransform(level_set.transform().copy());
    grid->setName(name);
    grid->setGridClass(openvdb::GRID_UNKNOWN);
    for (auto it = level_set.beginMeta(); it != level_set.endMeta(); ++it) {
        // The level set's own metadata (origin, creator) except OpenVDB's grid-class entries.
        if (it->first == openvdb::GridBase::META_GRID_CLASS ||
            it->first == openvdb::GridBase::META_GRID_NAME) {
            continue;
        }
        grid->insertMeta(it->first, *it->second);
    }
    return grid;
}

void check_sizes(std::size_t voxels, std::size_t values, const char* what) {
    if (voxels != values) {
        throw DataError(std::string(what) + ": " + std::to_string(values) + " values for " +
                        std::to_string(voxels) + " voxels");
    }
}
}  // namespace

openvdb::Vec3SGrid::Ptr make_color_grid(const openvdb::FloatGrid& level_set,
                                        const std::vector<openvdb::Coord>& voxels,
                                        const std::vector<std::array<std::uint8_t, 3>>& rgb,
                                        const std::vector<float>& weight) {
    check_sizes(voxels.size(), rgb.size(), "color grid");
    check_sizes(voxels.size(), weight.size(), "color grid weights");
    auto grid = empty_grid_like<openvdb::Vec3SGrid>(level_set, kColorGridName);
    grid->setVectorType(openvdb::VEC_INVARIANT);
    auto accessor = grid->getAccessor();
    for (std::size_t i = 0; i < voxels.size(); ++i) {
        if (!(weight[i] > 0.0f)) continue;
        accessor.setValue(
            voxels[i], openvdb::Vec3s(rgb[i][0] / 255.0f, rgb[i][1] / 255.0f, rgb[i][2] / 255.0f));
    }
    return grid;
}

openvdb::FloatGrid::Ptr make_intensity_grid(const openvdb::FloatGrid& level_set,
                                            const std::vector<openvdb::Coord>& voxels,
                                            const std::vector<float>& intensity) {
    check_sizes(voxels.size(), intensity.size(), "intensity grid");
    auto grid = empty_grid_like<openvdb::FloatGrid>(level_set, kIntensityGridName);
    auto accessor = grid->getAccessor();
    for (std::size_t i = 0; i < voxels.size(); ++i) {
        if (std::isfinite(intensity[i])) accessor.setValue(voxels[i], intensity[i]);
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
