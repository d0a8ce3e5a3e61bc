// Colour and intensity grids beside a level set, from the values of vertices on its surface: which
// voxels they reach, their values, names, transform and metadata, read back from the file with
// OpenVDB's own API.
#include <gtest/gtest.h>
#include <openvdb/io/File.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <random>

#include "shine/bake/surface_attribute_grids.hpp"
#include "shine/core/error.hpp"

namespace shine {
namespace {

constexpr float kRadiusM = 2.0f;
constexpr float kVoxelM = 0.1f;
const Eigen::Vector3f kCentreM(0.3f, -0.2f, 0.1f);
constexpr std::array<std::uint8_t, 3> kRed{255, 0, 0};
constexpr std::array<std::uint8_t, 3> kBlue{0, 0, 255};

openvdb::FloatGrid::Ptr sphere() {
    openvdb::initialize();
    auto grid = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
        kRadiusM, openvdb::Vec3f(kCentreM.x(), kCentreM.y(), kCentreM.z()), kVoxelM, 3.0f);
    grid->setName("surface");
    grid->insertMeta("shine_origin_world_m", openvdb::Vec3DMetadata(openvdb::Vec3d(100, 200, 0)));
    return grid;
}

/// Points on the sphere: red above its centre, blue below; every fifth one unknown.
struct SphereVertices {
    std::vector<Eigen::Vector3f> points;
    std::vector<std::array<std::uint8_t, 3>> rgb;
    std::vector<std::uint8_t> known;
    std::vector<float> intensity;
};

SphereVertices sphere_vertices() {
    SphereVertices v;
    std::mt19937 rng(7);
    std::normal_distribution<float> normal(0.0f, 1.0f);
    for (int i = 0; i < 60000; ++i) {
        const Eigen::Vector3f direction =
            Eigen::Vector3f(normal(rng), normal(rng), normal(rng)).normalized();
        v.points.push_back(kCentreM + kRadiusM * direction);
        v.rgb.push_back(direction.z() > 0.0f ? kRed : kBlue);
        v.known.push_back(i % 5 != 0);
        v.intensity.push_back(i % 5 == 0 ? std::nanf("") : direction.z());
    }
    return v;
}

TEST(SurfaceAttributeGrids, VoxelsNextToVerticesTakeTheirMeanValues) {
    const auto level_set = sphere();
    const SphereVertices v = sphere_vertices();
    const auto colour = color_grid_from_vertices(*level_set, v.points, v.rgb, v.known);
    const auto intensity = intensity_grid_from_vertices(*level_set, v.points, v.intensity);
    // The corners of the cells the surface crosses: 2.8 layers of voxels on this sphere.
    const double shell_voxels = 4.0 * M_PI * kRadiusM * kRadiusM / (kVoxelM * kVoxelM);
    EXPECT_GT(colour->activeVoxelCount(), 2.0 * shell_voxels);
    EXPECT_LT(colour->activeVoxelCount(), 3.5 * shell_voxels);
    EXPECT_EQ(intensity->activeVoxelCount(), colour->activeVoxelCount());
    auto level = level_set->getConstAccessor();
    auto intensity_at = intensity->getConstAccessor();
    const openvdb::math::Transform& xform = level_set->transform();
    for (auto it = colour->cbeginValueOn(); it; ++it) {
        ASSERT_TRUE(level.isValueOn(it.getCoord()));
        // A cell's corner: within one cell diagonal of the surface.
        ASSERT_LE(std::abs(level.getValue(it.getCoord())), std::sqrt(3.0f) * kVoxelM + 1e-4f);
        const openvdb::Vec3d p = xform.indexToWorld(it.getCoord());
        const double height_m = p.z() - kCentreM.z();
        if (std::abs(height_m) < 2.0 * kVoxelM) continue;  // both colours meet at the equator
        const openvdb::Vec3s expected =
            height_m > 0.0 ? openvdb::Vec3s(1, 0, 0) : openvdb::Vec3s(0, 0, 1);
        EXPECT_EQ(*it, expected) << it.getCoord();
        EXPECT_NEAR(intensity_at.getValue(it.getCoord()), height_m / kRadiusM, 0.1);
    }
}

// The grids are built in parallel by leaf; each voxel's sum must still run over its vertices in
// vertex order, as the definition's one pass does: the same bits, voxel for voxel.
TEST(SurfaceAttributeGrids, ValuesAreTheMeansOfOnePassOverTheVerticesBitForBit) {
    const auto level_set = sphere();
    const SphereVertices v = sphere_vertices();
    std::map<std::array<int, 3>, openvdb::Vec4f> sums;  // the definition, serially
    auto level = level_set->getConstAccessor();
    for (std::size_t i = 0; i < v.points.size(); ++i) {
        if (!std::isfinite(v.intensity[i])) continue;
        const Eigen::Vector3f& p = v.points[i];
        const openvdb::Coord base = openvdb::Coord::floor(
            level_set->transform().worldToIndex(openvdb::Vec3d(p.x(), p.y(), p.z())));
        for (int corner = 0; corner < 8; ++corner) {
            const openvdb::Coord ijk =
                base.offsetBy(corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
            if (!level.isValueOn(ijk)) continue;
            openvdb::Vec4f& sum = sums[{ijk.x(), ijk.y(), ijk.z()}];
            sum = sum + openvdb::Vec4f(v.intensity[i], 0.0f, 0.0f, 1.0f);
        }
    }
    const auto intensity = intensity_grid_from_vertices(*level_set, v.points, v.intensity);
    ASSERT_EQ(intensity->activeVoxelCount(), sums.size());
    auto at = intensity->getConstAccessor();
    std::size_t negative = 0;
    for (const auto& [ijk, sum] : sums) {
        const openvdb::Coord c(ijk[0], ijk[1], ijk[2]);
        ASSERT_TRUE(at.isValueOn(c)) << c;
        ASSERT_EQ(at.getValue(c), sum[0] / sum[3]) << c;  // exact
        negative += ijk[0] < 0 || ijk[1] < 0 || ijk[2] < 0;
    }
    EXPECT_GT(negative, sums.size() / 2);  // leaves on both sides of the index origin
}

TEST(SurfaceAttributeGrids, UnknownValuesReachNoVoxel) {
    const auto level_set = sphere();
    SphereVertices v = sphere_vertices();
    std::fill(v.known.begin(), v.known.end(), 0);
    std::fill(v.intensity.begin(), v.intensity.end(), std::nanf(""));
    EXPECT_EQ(color_grid_from_vertices(*level_set, v.points, v.rgb, v.known)->activeVoxelCount(),
              0u);
    EXPECT_EQ(intensity_grid_from_vertices(*level_set, v.points, v.intensity)->activeVoxelCount(),
              0u);
    EXPECT_THROW(intensity_grid_from_vertices(*level_set, v.points, {}), DataError);
    EXPECT_THROW(color_grid_from_vertices(*level_set, v.points, v.rgb, {}), DataError);
}

TEST(SurfaceAttributeGrids, GridsAreWrittenBesideTheLevelSetAndReadBackWithOpenVdb) {
    const auto level_set = sphere();
    const SphereVertices v = sphere_vertices();
    const auto colour = color_grid_from_vertices(*level_set, v.points, v.rgb, v.known);
    const auto intensity = intensity_grid_from_vertices(*level_set, v.points, v.intensity);
    const std::filesystem::path dir = std::filesystem::path(SHINE_TEST_TMP_DIR) / "attribute_grids";
    std::filesystem::create_directories(dir);
    const std::filesystem::path path = dir / "surface.vdb";
    write_surface_grids(path, level_set, {colour, intensity});

    openvdb::io::File file(path.string());
    file.open();
    std::vector<std::string> names;
    for (auto it = file.beginName(); it != file.endName(); ++it) names.push_back(it.gridName());
    EXPECT_EQ(names, (std::vector<std::string>{"color", "intensity", "surface"}));  // sorted
    auto color = openvdb::gridPtrCast<openvdb::Vec3SGrid>(file.readGrid("color"));
    auto inten = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("intensity"));
    auto level = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("surface"));
    file.close();
    ASSERT_TRUE(color && inten && level);
    EXPECT_EQ(level->getGridClass(), openvdb::GRID_LEVEL_SET);
    EXPECT_EQ(color->getGridClass(), openvdb::GRID_UNKNOWN);
    EXPECT_TRUE(color->transform() == level->transform());
    EXPECT_EQ(color->metaValue<openvdb::Vec3d>("shine_origin_world_m"),
              openvdb::Vec3d(100, 200, 0));
    EXPECT_EQ(color->activeVoxelCount(), colour->activeVoxelCount());
    auto written = colour->getConstAccessor();
    for (auto it = color->cbeginValueOn(); it; ++it) {
        EXPECT_EQ(*it, written.getValue(it.getCoord()));
    }
    EXPECT_EQ(inten->activeVoxelCount(), intensity->activeVoxelCount());
}

}  // namespace
}  // namespace shine
