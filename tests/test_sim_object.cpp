// The object-scale scene (`shine simulate --scene object`): its size, a scanner that sees the
// object from every turntable pose, determinism for a seed, and the written sequence.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "shine/core/error.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/ply.hpp"
#include "shine/sim/lidar_simulator.hpp"
#include "shine/sim/mesh_primitives.hpp"
#include "shine/sim/object_scene.hpp"
#include "shine/sim/object_simulation.hpp"

namespace fs = std::filesystem;

namespace shine::sim {
namespace {

constexpr double kSizeToleranceM = 1e-6;  // float vertices of a ~0.3 m object
/// Points this far above the plate's top (z = 0) lie on the object, not on the plate.
constexpr float kAbovePlateM = 0.002f;

std::string file_bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

TEST(ObjectScene, IsShoeboxSizedOnAPlateWithFineTriangles) {
    const ObjectSceneConfig config;
    const ObjectScene scene = make_object_scene(config);
    // The object (plate excluded): about 0.3 m across and 0.16 m high (the bottle), standing on
    // the plate (z = 0) and inside it.
    const Eigen::Vector3d size = scene.object_m.sizes();
    EXPECT_GT(size.x(), 0.25);
    EXPECT_LT(size.x(), 0.45);
    EXPECT_GT(size.y(), 0.15);
    EXPECT_LT(size.y(), 0.45);
    EXPECT_NEAR(size.z(), 1.6 * config.box_height_m, kSizeToleranceM);  // the bottle is tallest
    EXPECT_NEAR(scene.object_m.min().z(), 0.0, 0.05 * config.box_height_m);  // tilted box may dip
    EXPECT_LT(scene.object_m.max().head<2>().cwiseAbs().maxCoeff(), config.plate_size_m / 2);
    EXPECT_EQ(scene.num_parts, 7u);
    EXPECT_LE(max_edge_length(scene.mesh), config.max_edge_length_m * (1.0 + 1e-5));
    EXPECT_TRUE(scene.mesh.face_observed.empty());
}

TEST(ObjectScene, SameSeedSameMeshOtherSeedOtherLayout) {
    ObjectSceneConfig config;
    const ObjectScene a = make_object_scene(config);
    const ObjectScene b = make_object_scene(config);
    ASSERT_EQ(a.mesh.vertices.size(), b.mesh.vertices.size());
    ASSERT_EQ(a.mesh.triangles, b.mesh.triangles);
    for (std::size_t i = 0; i < a.mesh.vertices.size(); ++i) {
        ASSERT_EQ(a.mesh.vertices[i], b.mesh.vertices[i]) << i;
    }
    config.seed = 2;
    const ObjectScene c = make_object_scene(config);
    EXPECT_FALSE(
        c.mesh.vertices.size() == a.mesh.vertices.size() &&
        std::equal(a.mesh.vertices.begin(), a.mesh.vertices.end(), c.mesh.vertices.begin()));
}

TEST(ObjectScene, RejectsBadSizesNamingTheField) {
    ObjectSceneConfig config;
    config.plate_size_m = 0.2;  // smaller than the box
    try {
        make_object_scene(config);
        FAIL() << "accepted a plate smaller than the object";
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("plate_size_m"), std::string::npos) << e.what();
    }
    config = ObjectSceneConfig{};
    config.max_edge_length_m = 0.0;
    EXPECT_THROW(make_object_scene(config), ConfigError);
}

TEST(ObjectSimulation, TurntablePosesCircleTheObjectAndLookAtIt) {
    const TurntableConfig config;
    const std::vector<Eigen::Isometry3d> poses = make_turntable_poses(config);
    ASSERT_EQ(poses.size(), config.ring_heights_m.size() * config.scans_per_ring);
    const Eigen::Vector3d aim(0.0, 0.0, config.aim_height_m);
    for (std::size_t i = 0; i < poses.size(); ++i) {
        const Eigen::Isometry3d& T = poses[i];
        EXPECT_NEAR(T.translation().head<2>().norm(), config.distance_m, 1e-12);
        EXPECT_NEAR(T.translation().z(), config.ring_heights_m[i / config.scans_per_ring], 1e-12);
        const Eigen::Vector3d forward = T.linear().col(0);
        EXPECT_NEAR(forward.dot((aim - T.translation()).normalized()), 1.0, 1e-12);
        EXPECT_NEAR((T.linear().transpose() * T.linear() - Eigen::Matrix3d::Identity()).norm(), 0.0,
                    1e-12);
        EXPECT_GT(T.linear().col(2).z(), 0.0);  // z up-ish
    }
}

TEST(ObjectSimulation, EveryScanHitsTheObjectDensely) {
    const ObjectScene scene = make_object_scene(ObjectSceneConfig{});
    const RayCaster caster(scene.mesh);
    const LidarConfig lidar = object_scanner_defaults();
    const std::vector<Eigen::Isometry3d> poses = make_turntable_poses(TurntableConfig{});
    for (std::size_t i = 0; i < poses.size(); i += 5) {
        const LidarScan scan = simulate_scan(caster, lidar, poses[i], 7);
        std::size_t on_object = 0;
        for (const Eigen::Vector3f& p : scan.points_sensor) {
            const Eigen::Vector3d p_world = poses[i] * p.cast<double>();
            on_object += p_world.z() > kAbovePlateM;
            ASSERT_LE(std::abs(p_world.x()), 0.5 * 0.5 + 1e-4);  // nothing but the plate and object
        }
        // Measured over all 24 scans: 12,469 to 18,811 of 31,930 to 40,680 points per scan lie
        // on the object (1.6 mm ray spacing at 1 m); the plate takes the rest of the hits.
        EXPECT_GT(on_object, 12000u) << "scan " << i;
        EXPECT_GT(scan.points_sensor.size(), 30000u) << "scan " << i;
    }
}

TEST(ObjectSimulation, WritesTheKittiLayoutDeterministically) {
    ObjectSimulationConfig config;
    config.turntable.scans_per_ring = 3;
    config.turntable.ring_heights_m = {0.4};
    config.lidar.range_noise_sigma_m = 0.001;
    config.show_progress = false;
    const fs::path dir_a = fs::path(SHINE_TEST_TMP_DIR) / "sim_object_a";
    const fs::path dir_b = fs::path(SHINE_TEST_TMP_DIR) / "sim_object_b";
    fs::remove_all(dir_a);
    fs::remove_all(dir_b);
    const SimulationSummary a = simulate_object_sequence(config, dir_a);
    const SimulationSummary b = simulate_object_sequence(config, dir_b);
    EXPECT_EQ(a.num_frames, 3);
    EXPECT_EQ(a.total_points, b.total_points);
    for (const char* name :
         {"velodyne/000000.bin", "velodyne/000002.bin", "poses.txt", "gt_mesh.ply"}) {
        EXPECT_EQ(file_bytes(dir_a / name), file_bytes(dir_b / name)) << name;
    }
    EXPECT_FALSE(fs::exists(dir_a / "velodyne/000003.bin"));
    EXPECT_EQ(read_kitti_poses(dir_a / "poses.txt").size(), 3u);
    const TriangleMesh gt = read_ply_mesh(dir_a / "gt_mesh.ply");
    ASSERT_EQ(gt.face_observed.size(), gt.triangles.size());
    EXPECT_GT(a.num_observed_triangles, 0u);
    EXPECT_LT(a.num_observed_triangles, a.num_triangles);  // the bottom and far sides are unseen
    EXPECT_NE(file_bytes(dir_a / "simulation.json").find("\"azimuth_fov_deg\": 30"),
              std::string::npos);
    // Another seed: other noise, other scans.
    config.seed = 5;
    const fs::path dir_c = fs::path(SHINE_TEST_TMP_DIR) / "sim_object_c";
    fs::remove_all(dir_c);
    simulate_object_sequence(config, dir_c);
    EXPECT_NE(file_bytes(dir_a / "velodyne/000000.bin"), file_bytes(dir_c / "velodyne/000000.bin"));
}

TEST(ObjectSimulation, NarrowFieldOfViewSpreadsAzimuthsOverIt) {
    LidarConfig lidar = object_scanner_defaults();
    const double first =
        std::atan2(lidar_ray_direction(lidar, 0, 0).y(), lidar_ray_direction(lidar, 0, 0).x());
    const double last = std::atan2(lidar_ray_direction(lidar, 0, lidar.azimuth_steps - 1).y(),
                                   lidar_ray_direction(lidar, 0, lidar.azimuth_steps - 1).x());
    EXPECT_NEAR(first, -15.0 * M_PI / 180.0, 1e-12);
    EXPECT_NEAR(last, 15.0 * M_PI / 180.0, 1e-12);
    lidar.azimuth_fov_deg = 0.0;
    EXPECT_THROW(validate(lidar), ConfigError);
}

}  // namespace
}  // namespace shine::sim
