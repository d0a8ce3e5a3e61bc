#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <utility>

#include "shine/core/error.hpp"
#include "shine/sim/mesh_primitives.hpp"
#include "shine/sim/street_scene.hpp"

namespace {

using shine::TriangleMesh;
using shine::sim::SceneObjectKind;
using shine::sim::ScenePart;
using shine::sim::StreetScene;
using shine::sim::StreetSceneConfig;

constexpr double kMinTriangleAreaM2 = 1e-6;  // 1 mm^2: far above float noise, far below 0.3 m cells
constexpr float kEdgeSlackM = 1e-5f;

StreetSceneConfig small_config(std::uint64_t seed) {
    StreetSceneConfig config;
    config.seed = seed;
    config.start_x_m = -10.0;
    config.length_m = 70.0;
    return config;
}

Eigen::Vector3d face_normal_times2(const TriangleMesh& mesh, const Eigen::Vector3i& t) {
    const Eigen::Vector3d a = mesh.vertices[t[0]].cast<double>();
    const Eigen::Vector3d b = mesh.vertices[t[1]].cast<double>();
    const Eigen::Vector3d c = mesh.vertices[t[2]].cast<double>();
    return (b - a).cross(c - a);
}

/// Signed volume of triangles [first, first + count) (divergence theorem).
double signed_volume(const TriangleMesh& mesh, std::size_t first, std::size_t count) {
    double volume = 0.0;
    for (std::size_t i = first; i < first + count; ++i) {
        const auto& t = mesh.triangles[i];
        volume += mesh.vertices[t[0]].cast<double>().dot(mesh.vertices[t[1]].cast<double>().cross(
                      mesh.vertices[t[2]].cast<double>())) /
                  6.0;
    }
    return volume;
}

/// True if every directed edge appears exactly once and its reverse exactly once: a closed,
/// consistently oriented surface without T-junctions.
bool is_closed_and_consistent(const TriangleMesh& mesh, std::size_t first, std::size_t count) {
    std::map<std::pair<int, int>, int> directed;
    for (std::size_t i = first; i < first + count; ++i) {
        const auto& t = mesh.triangles[i];
        for (int k = 0; k < 3; ++k) ++directed[{t[k], t[(k + 1) % 3]}];
    }
    for (const auto& [edge, n] : directed) {
        if (n != 1) return false;
        const auto reverse = directed.find({edge.second, edge.first});
        if (reverse == directed.end() || reverse->second != 1) return false;
    }
    return true;
}

TEST(MeshPrimitives, PrimitivesAreClosedOutwardAndRefineConforming) {
    std::vector<std::pair<std::string, TriangleMesh>> meshes;
    meshes.emplace_back("box", shine::sim::make_box_mesh({0, 0, 0}, {2.0f, 1.0f, 0.7f}));
    meshes.emplace_back("L prism", shine::sim::make_prism_mesh(
                                       {{0, 0}, {4, 0}, {4, 1}, {1, 1}, {1, 3}, {0, 3}}, 2.5f));
    meshes.emplace_back("cylinder", shine::sim::make_cylinder_mesh(0.5f, 2.0f, 12));
    meshes.emplace_back("ellipsoid", shine::sim::make_ellipsoid_mesh({1.0f, 2.0f, 0.5f}, 2));
    meshes.emplace_back("grid L prism",
                        shine::sim::make_grid_prism_mesh(
                            {{0, 0}, {4, 0}, {4, 1}, {1, 1}, {1, 3}, {0, 3}}, -0.5f, 2.0f, 0.3f));
    meshes.emplace_back("grid cylinder", shine::sim::make_grid_cylinder_mesh(0.12f, 6.0f, 0.3f));
    const double expected_volume[] = {
        2.0 * 1.0 * 0.7, (4.0 * 1 + 1.0 * 2) * 2.5, 0.0, 0.0, (4.0 * 1 + 1.0 * 2) * 2.5, 0.0};
    for (std::size_t i = 0; i < meshes.size(); ++i) {
        auto& [name, mesh] = meshes[i];
        const double volume_before = signed_volume(mesh, 0, mesh.triangles.size());
        EXPECT_TRUE(is_closed_and_consistent(mesh, 0, mesh.triangles.size())) << name;
        EXPECT_GT(volume_before, 0.0) << name;
        if (expected_volume[i] > 0.0) {
            EXPECT_NEAR(volume_before, expected_volume[i], 1e-5) << name;
        }
        shine::sim::refine_to_max_edge(mesh, 0.2f);
        EXPECT_LE(shine::sim::max_edge_length(mesh), 0.2f + kEdgeSlackM) << name;
        EXPECT_TRUE(is_closed_and_consistent(mesh, 0, mesh.triangles.size())) << name;
        // Midpoint splits of planar faces keep the volume.
        EXPECT_NEAR(signed_volume(mesh, 0, mesh.triangles.size()), volume_before, 1e-4) << name;
    }
    EXPECT_THROW(shine::sim::make_prism_mesh({{0, 0}, {0, 1}, {1, 0}}, 1.0f), shine::ConfigError);
    EXPECT_THROW(shine::sim::make_box_mesh({0, 0, 0}, {1, 0, 1}), shine::ConfigError);
    EXPECT_THROW(
        shine::sim::make_grid_prism_mesh({{0, 0}, {2, 0}, {2, 2}, {1, 3}}, 0.0f, 1.0f, 0.3f),
        shine::ConfigError);
}

TEST(StreetScene, SameSeedIdenticalDifferentSeedDifferent) {
    const StreetScene a = shine::sim::make_street_scene(small_config(7));
    const StreetScene b = shine::sim::make_street_scene(small_config(7));
    const StreetScene c = shine::sim::make_street_scene(small_config(8));
    ASSERT_EQ(a.mesh.vertices.size(), b.mesh.vertices.size());
    ASSERT_EQ(a.mesh.triangles.size(), b.mesh.triangles.size());
    EXPECT_TRUE(a.mesh.vertices == b.mesh.vertices);
    EXPECT_TRUE(a.mesh.triangles == b.mesh.triangles);
    EXPECT_FALSE(a.mesh.vertices.size() == c.mesh.vertices.size() &&
                 a.mesh.vertices == c.mesh.vertices);
    // Layouts differ in more than one detail: compare per-kind object counts and building parts.
    int differing_counts = 0;
    for (const auto kind :
         {SceneObjectKind::kBuilding, SceneObjectKind::kTree, SceneObjectKind::kCar,
          SceneObjectKind::kPole, SceneObjectKind::kPedestrian}) {
        differing_counts += a.count_objects(kind) != c.count_objects(kind);
    }
    const std::size_t parts_a = a.parts.size(), parts_c = c.parts.size();
    EXPECT_TRUE(differing_counts > 0 || parts_a != parts_c);
}

TEST(StreetScene, TessellationNoDegenerateTrianglesAndMaxEdge) {
    for (const double max_edge : {0.3, 0.5}) {
        StreetSceneConfig config = small_config(3);
        config.max_edge_length_m = max_edge;
        const StreetScene scene = shine::sim::make_street_scene(config);
        EXPECT_LE(shine::sim::max_edge_length(scene.mesh),
                  static_cast<float>(max_edge) + kEdgeSlackM);
        double min_area = std::numeric_limits<double>::max();
        for (const auto& t : scene.mesh.triangles) {
            ASSERT_TRUE(t[0] != t[1] && t[1] != t[2] && t[0] != t[2]);
            min_area = std::min(min_area, 0.5 * face_normal_times2(scene.mesh, t).norm());
        }
        EXPECT_GT(min_area, kMinTriangleAreaM2) << "max edge " << max_edge;
    }
}

TEST(StreetScene, ObjectsAreClosedAndOutwardGroundFacesUp) {
    const StreetSceneConfig config = small_config(5);
    const StreetScene scene = shine::sim::make_street_scene(config);
    std::size_t covered = 0;
    int ground_parts = 0;
    for (const ScenePart& part : scene.parts) {
        EXPECT_EQ(part.first_triangle, covered);
        covered += part.num_triangles;
        ASSERT_GT(part.num_triangles, 0u);
        if (part.kind == SceneObjectKind::kGround) {
            ++ground_parts;
            EXPECT_FALSE(part.closed);
            // Road and sidewalks face up; curb faces face the road centre line y = 0.
            for (std::size_t i = part.first_triangle; i < part.first_triangle + part.num_triangles;
                 ++i) {
                const Eigen::Vector3d n =
                    face_normal_times2(scene.mesh, scene.mesh.triangles[i]).normalized();
                const double y = scene.mesh.vertices[scene.mesh.triangles[i][0]].y();
                const bool up = n.z() > 0.999;
                const bool curb = std::abs(n.z()) < 1e-3 && n.y() * y < 0.0 &&
                                  std::abs(std::abs(y) - config.road_width_m / 2) < 1e-4;
                ASSERT_TRUE(up || curb) << "ground triangle " << i;
            }
            continue;
        }
        EXPECT_TRUE(part.closed);
        EXPECT_TRUE(is_closed_and_consistent(scene.mesh, part.first_triangle, part.num_triangles))
            << shine::sim::to_string(part.kind) << " part at triangle " << part.first_triangle;
        EXPECT_GT(signed_volume(scene.mesh, part.first_triangle, part.num_triangles), 1e-4)
            << shine::sim::to_string(part.kind) << " part at triangle " << part.first_triangle;
    }
    EXPECT_EQ(covered, scene.mesh.triangles.size());
    EXPECT_EQ(ground_parts, 1);
}

TEST(StreetScene, ObjectsHavePlausibleSizesAndCounts) {
    const StreetSceneConfig config = small_config(9);
    const StreetScene scene = shine::sim::make_street_scene(config);
    EXPECT_GE(scene.count_objects(SceneObjectKind::kBuilding), 4u);
    EXPECT_GE(scene.count_objects(SceneObjectKind::kTree), 4u);
    EXPECT_GE(scene.count_objects(SceneObjectKind::kCar), 4u);
    EXPECT_GE(scene.count_objects(SceneObjectKind::kPole), 1u);
    EXPECT_GE(scene.count_objects(SceneObjectKind::kPedestrian), 2u);
    // Bounding box per object.
    std::map<std::size_t, std::pair<SceneObjectKind, Eigen::AlignedBox3f>> objects;
    for (const ScenePart& part : scene.parts) {
        auto& [kind, box] = objects[part.object_index];
        kind = part.kind;
        for (std::size_t i = part.first_triangle; i < part.first_triangle + part.num_triangles;
             ++i) {
            for (int k = 0; k < 3; ++k) box.extend(scene.mesh.vertices[scene.mesh.triangles[i][k]]);
        }
    }
    for (const auto& [index, entry] : objects) {
        const auto& [kind, box] = entry;
        const Eigen::Vector3f size = box.sizes();
        EXPECT_GE(box.min().x(), config.start_x_m - 1e-3);
        EXPECT_LE(box.max().x(), config.start_x_m + config.length_m + 1e-3);
        switch (kind) {
            case SceneObjectKind::kPedestrian:
                EXPECT_GT(box.max().z() - config.curb_height_m, 1.5f);
                EXPECT_LT(box.max().z() - config.curb_height_m, 1.9f);
                break;
            case SceneObjectKind::kCar:
                EXPECT_GT(std::max(size.x(), size.y()), 3.7f);
                EXPECT_LT(std::max(size.x(), size.y()), 5.6f);
                EXPECT_GT(size.z(), 1.3f);
                EXPECT_LT(size.z(), 2.4f);
                break;
            case SceneObjectKind::kBuilding:
                EXPECT_GT(size.z(), config.building_height_min_m);
                break;
            case SceneObjectKind::kTree:
                EXPECT_GT(size.z(), 3.5f);
                break;
            case SceneObjectKind::kPole:
                EXPECT_GT(size.z(), 4.0f);
                EXPECT_LT(size.z(), 8.2f);
                break;
            case SceneObjectKind::kGround:
                EXPECT_NEAR(size.x(), config.length_m, 1e-3);
                break;
        }
    }
}

TEST(StreetScene, InvalidConfigNamesTheField) {
    StreetSceneConfig config;
    config.max_edge_length_m = 0.0;
    try {
        shine::sim::make_street_scene(config);
        FAIL() << "expected ConfigError";
    } catch (const shine::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("max_edge_length_m"), std::string::npos);
    }
    config = StreetSceneConfig{};
    config.building_height_max_m = 1.0;
    EXPECT_THROW(shine::sim::make_street_scene(config), shine::ConfigError);
}

}  // namespace
