// tsdf.vdb: a volume survives the round trip bit for bit, and bad files are refused by name.
#include <gtest/gtest.h>
#include <openvdb/io/File.h>

#include <filesystem>
#include <fstream>

#include "shine/core/error.hpp"
#include "shine/tsdf/tsdf_file.hpp"
#include "shine/tsdf/tsdf_mesh.hpp"

using namespace shine;
namespace fs = std::filesystem;

namespace {

fs::path tmp_dir(const std::string& name) {
    const fs::path dir = fs::path(SHINE_TEST_TMP_DIR) / "tsdf_file" / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

/// A few rays onto a tilted plane, seen from a sensor far from the world origin.
TsdfVolume sample_volume(bool carving) {
    TsdfConfig config;
    config.voxel_size_m = 0.2;
    config.trunc_m = 0.6;
    config.space_carving = carving;
    TsdfVolume volume(config, Eigen::Vector3d(500000.0, 4100000.0, 0.0));
    std::vector<Eigen::Vector3d> points;
    for (int i = -20; i <= 20; ++i) {
        for (int j = -20; j <= 20; ++j) {
            const double x = 0.1 * i, y = 0.1 * j;
            points.emplace_back(x, y, -1.5 + 0.2 * x);
        }
    }
    volume.integrate(points, Eigen::Vector3d(0.3, 0.1, 0.4));
    return volume;
}

void expect_same_grid(const openvdb::FloatGrid& a, const openvdb::FloatGrid& b) {
    EXPECT_EQ(a.activeVoxelCount(), b.activeVoxelCount());
    EXPECT_EQ(a.background(), b.background());
    auto acc = b.getConstAccessor();
    for (auto it = a.cbeginValueOn(); it; ++it) {
        ASSERT_TRUE(acc.isValueOn(it.getCoord()));
        ASSERT_EQ(acc.getValue(it.getCoord()), *it);
    }
    EXPECT_EQ(a.transform(), b.transform());
}

}  // namespace

TEST(TsdfFile, RoundTripKeepsGridsParametersAndOrigin) {
    const fs::path dir = tmp_dir("round_trip");
    for (bool carving : {false, true}) {
        const TsdfVolume volume = sample_volume(carving);
        ASSERT_GT(volume.active_voxels(), 100u);
        write_tsdf_volume(dir / "tsdf.vdb", volume);
        const TsdfVolume read = read_tsdf_volume(dir / "tsdf.vdb");
        EXPECT_EQ(read.config().voxel_size_m, 0.2);
        EXPECT_EQ(read.config().trunc_m, 0.6);
        EXPECT_EQ(read.config().space_carving, carving);
        EXPECT_EQ(read.origin_world_m(), volume.origin_world_m());
        expect_same_grid(volume.tsdf_grid(), read.tsdf_grid());
        expect_same_grid(volume.weight_grid(), read.weight_grid());
        EXPECT_EQ(read.tsdf_grid().getName(), "tsdf");
        EXPECT_EQ(read.weight_grid().getName(), "weight");
        TsdfMeshConfig mesh_config;
        mesh_config.min_weight = 1.0f;
        const TriangleMesh a = extract_tsdf_mesh(volume, mesh_config);
        const TriangleMesh b = extract_tsdf_mesh(read, mesh_config);
        EXPECT_GT(a.triangles.size(), 10u);
        EXPECT_EQ(a.vertices, b.vertices);
        EXPECT_EQ(a.triangles, b.triangles);
    }
    // Nothing but the file itself is left in the directory (no temporary files).
    int files = 0;
    for (const auto& e : fs::directory_iterator(dir)) files += e.is_regular_file();
    EXPECT_EQ(files, 1);
}

TEST(TsdfFile, StandardToolsSeeTheOriginAndWorldPlacement) {
    const fs::path dir = tmp_dir("metadata");
    write_tsdf_volume(dir / "tsdf.vdb", sample_volume(false));
    openvdb::io::File file((dir / "tsdf.vdb").string());
    file.open(false);
    const auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid("tsdf"));
    const auto meta = file.getMetadata();
    file.close();
    ASSERT_TRUE(grid);
    const auto origin = grid->metaValue<openvdb::Vec3d>("shine_origin_world_m");
    EXPECT_EQ(origin, openvdb::Vec3d(500000.0, 4100000.0, 0.0));
    EXPECT_EQ(meta->metaValue<std::string>("shine_format"), "shine_tsdf");
    EXPECT_EQ(grid->getGridClass(), openvdb::GRID_LEVEL_SET);
    // Voxel (0, 0, -8) of a 0.2 m lattice: centre at z = (-8 + 0.5) * 0.2 = -1.5 m.
    const openvdb::Vec3d centre = grid->indexToWorld(openvdb::Coord(0, 0, -8));
    EXPECT_NEAR(centre.x(), 500000.1, 1e-6);
    EXPECT_NEAR(centre.z(), -1.5, 1e-6);
}

TEST(TsdfFile, BadFilesAreRefusedByName) {
    const fs::path dir = tmp_dir("bad");
    try {
        read_tsdf_volume(dir / "missing.vdb");
        FAIL();
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("missing.vdb"), std::string::npos) << e.what();
    }
    std::ofstream(dir / "garbage.vdb") << "not a vdb";
    try {
        read_tsdf_volume(dir / "garbage.vdb");
        FAIL();
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("garbage.vdb"), std::string::npos) << e.what();
    }
    // A valid .vdb that is not a TSDF volume (e.g. a surface.vdb).
    openvdb::initialize();
    auto level_set = openvdb::FloatGrid::create(0.3f);
    level_set->setName("surface");
    openvdb::io::File((dir / "surface.vdb").string()).write({level_set});
    try {
        read_tsdf_volume(dir / "surface.vdb");
        FAIL();
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("surface.vdb"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("not a ShineVDB TSDF volume"), std::string::npos);
    }
}
