// Colour and intensity grids beside a level set: surface points of a sphere's narrow band, the
// grids' names, transforms and values, read back from the file with OpenVDB's own API.
#include <gtest/gtest.h>
#include <openvdb/io/File.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <filesystem>

#include "shine/bake/surface_attribute_grids.hpp"
#include "shine/core/error.hpp"

namespace shine {
namespace {

constexpr float kRadiusM = 2.0f;
constexpr float kVoxelM = 0.1f;
constexpr double kMinNormalCosine = 0.98;

openvdb::FloatGrid::Ptr sphere() {
    openvdb::initialize();
    auto grid = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
        kRadiusM, openvdb::Vec3f(0.3f, -0.2f, 0.1f), kVoxelM, 3.0f);
    grid->setName("surface");
    grid->insertMeta("shine_origin_world_m", openvdb::Vec3DMetadata(openvdb::Vec3d(100, 200, 0)));
    return grid;
}

TEST(SurfaceAttributeGrids, SurfacePointsLieOnTheSphereWithOutwardNormals) {
    const auto grid = sphere();
    const LevelSetSurfacePoints surface = level_set_surface_points(*grid);
    ASSERT_EQ(surface.voxels.size(), grid->activeVoxelCount());
    const Eigen::Vector3d centre(0.3, -0.2, 0.1);
    for (std::size_t i = 0; i < surface.voxels.size(); ++i) {
        const Eigen::Vector3d r = surface.points_map[i] - centre;
        // Two Newton steps on a sampled distance: within a few mm of the true sphere.
        EXPECT_NEAR(r.norm(), kRadiusM, 0.01) << "voxel " << surface.voxels[i];
        // Central differences at the band's edge see the clamped background: up to 10 degrees
        // off there (measured: cosine 0.9845 at worst on this sphere).
        EXPECT_GT(surface.normals_map[i].dot(r.normalized()), kMinNormalCosine);
    }
}

TEST(SurfaceAttributeGrids, GridsAreWrittenBesideTheLevelSetAndReadBackWithOpenVdb) {
    const auto grid = sphere();
    const LevelSetSurfacePoints surface = level_set_surface_points(*grid);
    const std::size_t n = surface.voxels.size();
    std::vector<std::array<std::uint8_t, 3>> rgb(n);
    std::vector<float> weight(n, 1.0f), intensity(n);
    for (std::size_t i = 0; i < n; ++i) {
        // Red above the centre, blue below; every third voxel unseen and without intensity.
        const bool up = surface.points_map[i].z() > 0.1;
        rgb[i] =
            up ? std::array<std::uint8_t, 3>{255, 0, 0} : std::array<std::uint8_t, 3>{0, 0, 255};
        if (i % 3 == 0) weight[i] = 0.0f;
        intensity[i] = i % 3 == 0 ? std::nanf("") : static_cast<float>(surface.points_map[i].x());
    }
    const auto colour = make_color_grid(*grid, surface.voxels, rgb, weight);
    const auto reflectance = make_intensity_grid(*grid, surface.voxels, intensity);
    const std::filesystem::path dir = std::filesystem::path(SHINE_TEST_TMP_DIR) / "attribute_grids";
    std::filesystem::create_directories(dir);
    const std::filesystem::path path = dir / "surface.vdb";
    write_surface_grids(path, grid, {colour, reflectance});

    openvdb::io::File file(path.string());
    file.open();
    const auto names = [&] {
        std::vector<std::string> out;
        for (auto it = file.beginName(); it != file.endName(); ++it) out.push_back(it.gridName());
        return out;
    }();
    EXPECT_EQ(names, (std::vector<std::string>{"color", "intensity", "surface"}));  // sorted
    auto color = openvdb::gridPtrCast<openvdb::Vec3SGrid>(file.readGrid("color"));
    auto inten = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("intensity"));
    auto level = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("surface"));
    file.close();
    ASSERT_TRUE(color && inten && level);
    EXPECT_EQ(level->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_TRUE(color->transform() == level->transform());
    EXPECT_EQ(color->metaValue<openvdb::Vec3d>("shine_origin_world_m"),
              openvdb::Vec3d(100, 200, 0));
    EXPECT_EQ(color->activeVoxelCount(), n - (n + 2) / 3);
    EXPECT_EQ(inten->activeVoxelCount(), n - (n + 2) / 3);
    auto colour_at = color->getConstAccessor();
    auto intensity_at = inten->getConstAccessor();
    for (std::size_t i = 0; i < n; ++i) {
        const openvdb::Coord ijk = surface.voxels[i];
        if (i % 3 == 0) {
            EXPECT_FALSE(colour_at.isValueOn(ijk));
            EXPECT_FALSE(intensity_at.isValueOn(ijk));
            continue;
        }
        const openvdb::Vec3s c = colour_at.getValue(ijk);
        EXPECT_EQ(c, openvdb::Vec3s(rgb[i][0] / 255.0f, rgb[i][1] / 255.0f, rgb[i][2] / 255.0f));
        EXPECT_EQ(intensity_at.getValue(ijk), intensity[i]);
    }
    EXPECT_THROW(make_intensity_grid(*grid, surface.voxels, {}), DataError);
}

}  // namespace
}  // namespace shine
