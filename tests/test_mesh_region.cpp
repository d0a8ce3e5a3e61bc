// Meshing a level set region by region (write_level_set_mesh) against meshing it at once
// (mesh_level_set), and the streamed PLY writer behind it.
#include <gtest/gtest.h>
#include <openvdb/tools/Composite.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <Eigen/Geometry>
#include <array>
#include <cstring>
#include <filesystem>
#include <map>
#include <set>

#include "shine/core/error.hpp"
#include "shine/io/ply.hpp"
#include "shine/mesh/level_set_mesh.hpp"

namespace fs = std::filesystem;
using namespace shine;

namespace {

fs::path tmp_dir(const std::string& name) {
    const fs::path dir = fs::temp_directory_path() / ("shine_region_mesh_" + name);
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

/// Two overlapping spheres and a small one apart, 0.1 m voxels: surfaces cross many region
/// seams, and the big sphere's inside is made of tiles (no leaves), as in baked maps.
openvdb::FloatGrid::Ptr test_level_set() {
    openvdb::initialize();
    const float voxel_m = 0.1f;
    auto grid = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
        3.0f, openvdb::Vec3f(0.13f, -0.21f, 0.07f), voxel_m);
    auto second = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
        1.7f, openvdb::Vec3f(2.9f, 0.4f, -0.6f), voxel_m);
    auto third = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
        0.45f, openvdb::Vec3f(-4.6f, 3.3f, 1.9f), voxel_m);
    openvdb::tools::csgUnion(*grid, *second);
    openvdb::tools::csgUnion(*grid, *third);
    return grid;
}

using Position = std::array<std::uint32_t, 3>;

Position bits(const Eigen::Vector3f& v) {
    Position p;
    for (int a = 0; a < 3; ++a) std::memcpy(&p[a], &v[a], sizeof(float));
    return p;
}

/// The mesh's polygons as sets of vertex positions: both meshers write each of OpenVDB's quads as
/// two consecutive triangles, whose diagonal depends on where OpenVDB starts the quad.
std::multiset<std::set<Position>> quads_of(const TriangleMesh& mesh) {
    std::multiset<std::set<Position>> quads;
    for (std::size_t t = 0; t + 1 < mesh.triangles.size(); t += 2) {
        std::set<Position> corners;
        for (const std::size_t k : {t, t + 1}) {
            for (int i = 0; i < 3; ++i) corners.insert(bits(mesh.vertices[mesh.triangles[k][i]]));
        }
        quads.insert(corners);
    }
    return quads;
}

std::set<Position> referenced_positions(const TriangleMesh& mesh) {
    std::set<Position> positions;
    for (const auto& t : mesh.triangles) {
        for (int i = 0; i < 3; ++i) positions.insert(bits(mesh.vertices[t[i]]));
    }
    return positions;
}

/// Quads whose vector area points away from the big sphere's centre.
int outward_quads(const TriangleMesh& mesh) {
    int outward = 0;
    for (std::size_t t = 0; t + 1 < mesh.triangles.size(); t += 2) {
        Eigen::Vector3f area = Eigen::Vector3f::Zero(), centre = Eigen::Vector3f::Zero();
        for (const std::size_t k : {t, t + 1}) {
            const Eigen::Vector3f a = mesh.vertices[mesh.triangles[k][0]],
                                  b = mesh.vertices[mesh.triangles[k][1]],
                                  c = mesh.vertices[mesh.triangles[k][2]];
            area += (b - a).cross(c - a);
            centre += a + b + c;
        }
        if (area.dot(centre / 6.0f - Eigen::Vector3f(0.13f, -0.21f, 0.07f)) > 0.0f) ++outward;
    }
    return outward;
}

}  // namespace

TEST(RegionMesh, SameQuadsAsMeshingAtOnceWithSeamsWelded) {
    const auto grid = test_level_set();
    grid->insertMeta(kOriginMetadataKey, openvdb::Vec3DMetadata(openvdb::Vec3d(500000, 5e6, 12)));
    const TriangleMesh whole = mesh_level_set(*grid, MeshConfig{});
    ASSERT_GT(whole.triangles.size(), 10000u);
    ASSERT_EQ(whole.triangles.size() % 2, 0u);  // quads only at adaptivity 0
    const auto whole_quads = quads_of(whole);
    const auto whole_positions = referenced_positions(whole);
    const fs::path dir = tmp_dir("same");
    for (const int region_voxels : {8, 24, 256}) {
        SCOPED_TRACE("region_voxels " + std::to_string(region_voxels));
        const MeshFileStats stats =
            write_level_set_mesh(*grid, MeshConfig{}, dir / "mesh.ply", region_voxels);
        const TriangleMesh mesh = read_ply_mesh(dir / "mesh.ply");
        EXPECT_EQ(stats.triangles, mesh.triangles.size());
        EXPECT_EQ(stats.vertices, mesh.vertices.size());
        if (region_voxels == 8) {
            EXPECT_GT(stats.regions, 60u);
        }
        EXPECT_EQ(mesh.origin_world_m, Eigen::Vector3d(500000, 5e6, 12));
        EXPECT_EQ(mesh.triangles.size(), whole.triangles.size());
        EXPECT_TRUE(quads_of(mesh) == whole_quads) << "the polygons differ";
        // Welded: every vertex is used, no two share a position, and the positions are those of
        // the mesh made at once.
        const auto positions = referenced_positions(mesh);
        EXPECT_EQ(positions.size(), mesh.vertices.size());
        EXPECT_TRUE(positions == whole_positions);
        // Same winding, quad by quad (a quad's vector area does not depend on its diagonal).
        EXPECT_EQ(outward_quads(mesh), outward_quads(whole));
    }
    // Only the PLY remains: no temporary parts.
    std::size_t files = 0;
    for ([[maybe_unused]] const auto& entry : fs::directory_iterator(dir)) ++files;
    EXPECT_EQ(files, 1u);
}

TEST(RegionMesh, AdaptivityMeshesAtOnceAndBadRegionSizesAreRefused) {
    const auto grid = test_level_set();
    const fs::path dir = tmp_dir("adaptive");
    MeshConfig config;
    config.adaptivity = 0.5;
    const MeshFileStats stats = write_level_set_mesh(*grid, config, dir / "mesh.ply", 8);
    EXPECT_EQ(stats.regions, 1u);
    EXPECT_EQ(read_ply_mesh(dir / "mesh.ply").triangles.size(),
              mesh_level_set(*grid, config).triangles.size());
    EXPECT_THROW(write_level_set_mesh(*grid, MeshConfig{}, dir / "bad.ply", 12), ConfigError);
    EXPECT_THROW(write_level_set_mesh(*grid, MeshConfig{}, dir / "bad.ply", 0), ConfigError);
    EXPECT_FALSE(fs::exists(dir / "bad.ply"));
}

TEST(RegionMesh, TheCopyKeptInMemoryIsWhatTheFileReadsBackAs) {
    const auto grid = test_level_set();
    grid->insertMeta(kOriginMetadataKey, openvdb::Vec3DMetadata(openvdb::Vec3d(500000, 5e6, 12)));
    const fs::path dir = tmp_dir("copy");
    MeshConfig adaptive;
    adaptive.adaptivity = 0.5;
    // Region by region (seams welded) and at once (adaptivity).
    for (const MeshConfig& config : {MeshConfig{}, adaptive}) {
        SCOPED_TRACE("adaptivity " + std::to_string(config.adaptivity));
        TriangleMesh kept;
        kept.vertex_intensity = {1.0f};  // replaced, not appended to
        const MeshFileStats stats =
            write_level_set_mesh(*grid, config, dir / "mesh.ply", 24, &kept);
        const TriangleMesh back = read_ply_mesh(dir / "mesh.ply");
        ASSERT_GT(back.triangles.size(), 1000u);
        EXPECT_EQ(kept.triangles.size(), stats.triangles);
        EXPECT_TRUE(kept.vertices == back.vertices);
        EXPECT_TRUE(kept.triangles == back.triangles);
        EXPECT_EQ(kept.origin_world_m, back.origin_world_m);
        EXPECT_EQ(kept.face_observed, back.face_observed);
        EXPECT_TRUE(kept.vertex_intensity.empty());
        EXPECT_TRUE(kept.vertex_rgb.empty());
    }
}

TEST(RegionMesh, EmptyLevelSetGivesAValidEmptyPly) {
    openvdb::initialize();
    const auto grid = openvdb::FloatGrid::create(0.3f);
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    const fs::path dir = tmp_dir("empty");
    const MeshFileStats stats = write_level_set_mesh(*grid, MeshConfig{}, dir / "mesh.ply");
    EXPECT_EQ(stats.triangles, 0u);
    EXPECT_EQ(stats.regions, 0u);
    EXPECT_TRUE(read_ply_mesh(dir / "mesh.ply").empty());
}

TEST(PlyMeshStreamWriter, WritesWhatWritePlyMeshWritesAndNothingWithoutCommit) {
    const fs::path dir = tmp_dir("stream");
    TriangleMesh mesh;
    mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    mesh.triangles = {{0, 1, 2}, {0, 3, 1}, {1, 3, 2}};
    mesh.origin_world_m = Eigen::Vector3d(1.5, -2.25, 1e6);
    write_ply_mesh(dir / "at_once.ply", mesh);
    {
        PlyMeshStreamWriter writer(dir / "streamed.ply", mesh.origin_world_m);
        for (const auto& v : mesh.vertices) writer.add_vertex(v);
        for (const auto& t : mesh.triangles) writer.add_triangle(t[0], t[1], t[2]);
        EXPECT_THROW(writer.add_triangle(0, 1, 4), DataError);
        EXPECT_THROW(writer.add_triangle(-1, 1, 2), DataError);
        EXPECT_FALSE(fs::exists(dir / "streamed.ply"));
        writer.commit();
    }
    EXPECT_EQ(fs::file_size(dir / "streamed.ply"), fs::file_size(dir / "at_once.ply"));
    const TriangleMesh back = read_ply_mesh(dir / "streamed.ply");
    EXPECT_EQ(back.vertices, mesh.vertices);
    EXPECT_EQ(back.triangles, mesh.triangles);
    EXPECT_EQ(back.origin_world_m, mesh.origin_world_m);
    {
        // Abandoned (an exception on the way): no file, no temporary parts.
        PlyMeshStreamWriter writer(dir / "abandoned.ply", Eigen::Vector3d::Zero());
        writer.add_vertex({1, 2, 3});
    }
    std::set<std::string> names;
    for (const auto& entry : fs::directory_iterator(dir)) {
        names.insert(entry.path().filename().string());
    }
    EXPECT_EQ(names, (std::set<std::string>{"at_once.ply", "streamed.ply"}));
    // A directory that does not exist: the error names the file.
    try {
        PlyMeshStreamWriter writer(dir / "missing" / "mesh.ply", Eigen::Vector3d::Zero());
        FAIL() << "no error";
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("missing/mesh.ply"), std::string::npos) << e.what();
    }
}
