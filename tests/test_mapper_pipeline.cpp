// Map persistence and the map -> bake -> mesh chain on analytic scenes.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>

#include "shine/bake/level_set_bake.hpp"
#include "shine/bake/level_set_file.hpp"
#include "shine/core/error.hpp"
#include "shine/mapper/batch_mapper.hpp"
#include "shine/mesh/level_set_mesh.hpp"
#include "shine/model/map_file.hpp"

using namespace shine;
namespace fs = std::filesystem;

namespace {

// Bounds from measurements on this scene (median 0.11 voxel, 90th percentile 0.90 voxel at
// 0.1 m voxels; the tail is the far ground seen at grazing angles), with margin.
constexpr double kMedianBoundVoxels = 0.25;
constexpr double kP90BoundVoxels = 1.0;
constexpr double kMinOutwardShare = 0.90;  // measured 0.94

fs::path tmp_dir(const std::string& name) {
    const fs::path dir = fs::path(SHINE_TEST_TMP_DIR) / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

// Analytic scene: ground plane z = 0 and a sphere of radius 1 m centred at (4, 0, 1.2).
const Eigen::Vector3d kSphereCentre(4.0, 0.0, 1.2);
constexpr double kSphereRadiusM = 1.0;

double scene_sdf(const Eigen::Vector3d& p) {
    return std::min(p.z(), (p - kSphereCentre).norm() - kSphereRadiusM);
}

// Closest hit of a ray with the scene, or a negative value.
double cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d) {
    double best = -1.0;
    if (d.z() < -1e-9) best = -o.z() / d.z();
    const Eigen::Vector3d oc = o - kSphereCentre;
    const double b = oc.dot(d), c = oc.squaredNorm() - kSphereRadiusM * kSphereRadiusM;
    const double disc = b * b - c;
    if (disc >= 0.0) {
        const double t = -b - std::sqrt(disc);
        if (t > 0.0 && (best < 0.0 || t < best)) best = t;
    }
    return best;
}

// A spinning-LiDAR-like scan from `origin`, in the sensor frame (identity rotation).
Scan make_scan(const Eigen::Vector3d& origin, int beams, int azimuths, double max_range_m) {
    Scan scan;
    scan.T_world_sensor = Eigen::Isometry3d::Identity();
    scan.T_world_sensor.translation() = origin;
    for (int b = 0; b < beams; ++b) {
        const double elevation = (-30.0 + 28.0 * b / (beams - 1)) * M_PI / 180.0;
        for (int a = 0; a < azimuths; ++a) {
            const double azimuth = 2.0 * M_PI * a / azimuths;
            const Eigen::Vector3d d(std::cos(elevation) * std::cos(azimuth),
                                    std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
            const double t = cast(origin, d);
            if (t > 0.0 && t < max_range_m) scan.points_sensor.push_back((t * d).cast<float>());
        }
    }
    return scan;
}

MapperConfig small_config() {
    MapperConfig config;
    config.octree.leaf_size_m = 0.2;
    config.iterations = 1500;
    config.preprocess.min_range_m = 0.5;
    config.preprocess.max_range_m = 12.0;
    config.preprocess.voxel_downsample_m = 0.05;
    config.trainer.batch_size = 2048;
    return config;
}

}  // namespace

TEST(MapFile, SaveAndReloadGiveIdenticalSdfQueries) {
    MapperConfig config = small_config();
    config.iterations = 50;
    BatchMapper mapper(config);
    mapper.add_scan(make_scan({0, 0, 1.7}, 16, 360, 12.0));
    mapper.train();
    const fs::path path = tmp_dir("map_file") / "map.vdb";
    save_neural_map(path, mapper.sdf(), config_to_yaml(config));
    const LoadedMap loaded = load_neural_map(path);

    std::vector<Eigen::Vector3f> queries;
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-6.0f, 6.0f), uz(-0.5f, 2.5f);
    for (int i = 0; i < 5000; ++i) queries.emplace_back(u(rng), u(rng), uz(rng));
    std::vector<float> a, b;
    std::vector<std::uint8_t> va, vb;
    mapper.sdf().query(queries, QueryMask::kAnyLevel, a, va);
    loaded.sdf.query(queries, QueryMask::kAnyLevel, b, vb);
    int valid = 0;
    for (std::size_t i = 0; i < queries.size(); ++i) {
        ASSERT_EQ(va[i], vb[i]) << i;
        ASSERT_EQ(a[i], b[i]) << i;  // bit-identical
        valid += va[i];
    }
    EXPECT_GT(valid, 500);
    EXPECT_EQ(loaded.sdf.octree.num_corners(), mapper.sdf().octree.num_corners());
}

TEST(MapFile, CorruptOrForeignFilesGiveClearErrors) {
    const fs::path dir = tmp_dir("map_file_bad");
    EXPECT_THROW(load_neural_map(dir / "missing.vdb"), IoError);
    { std::ofstream(dir / "garbage.vdb") << "this is not a vdb file"; }
    try {
        load_neural_map(dir / "garbage.vdb");
        FAIL() << "no error";
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("garbage.vdb"), std::string::npos) << e.what();
    }
    // A valid level set is not a neural map.
    auto grid = openvdb::FloatGrid::create(0.3f);
    grid->setGridClass(openvdb::GRID_LEVEL_SET);
    write_level_set(dir / "surface.vdb", grid);
    EXPECT_THROW(load_neural_map(dir / "surface.vdb"), IoError);
    EXPECT_NO_THROW(read_level_set(dir / "surface.vdb"));
    // A truncated map.
    MapperConfig config = small_config();
    config.iterations = 1;
    BatchMapper mapper(config);
    mapper.add_scan(make_scan({0, 0, 1.7}, 8, 90, 12.0));
    save_neural_map(dir / "map.vdb", mapper.sdf(), config_to_yaml(config));
    const auto size = fs::file_size(dir / "map.vdb");
    fs::copy_file(dir / "map.vdb", dir / "truncated.vdb");
    fs::resize_file(dir / "truncated.vdb", size / 2);
    EXPECT_THROW(load_neural_map(dir / "truncated.vdb"), IoError);
}

TEST(BakeAndMesh, AnalyticPlaneAndSphereWithSubVoxelError) {
    MapperConfig config = small_config();
    BatchMapper mapper(config);
    for (const Eigen::Vector3d& origin :
         {Eigen::Vector3d(0, 0, 1.7), Eigen::Vector3d(1.5, 2.5, 1.7),
          Eigen::Vector3d(7.5, -1.0, 1.7), Eigen::Vector3d(4.0, -3.5, 1.7)}) {
        mapper.add_scan(make_scan(origin, 32, 720, 12.0));
    }
    mapper.train();
    BakeConfig bake;
    bake.voxel_size_m = 0.1;
    auto grid = bake_level_set(mapper.sdf(), bake);
    ASSERT_EQ(grid->getGridClass(), openvdb::GRID_LEVEL_SET);
    const TriangleMesh mesh = mesh_level_set(*grid, MeshConfig{});
    ASSERT_GT(mesh.triangles.size(), 1000u);

    // Distance of every vertex to the analytic surface, in voxels.
    std::vector<double> error_voxels;
    for (const auto& v : mesh.vertices) {
        error_voxels.push_back(std::abs(scene_sdf(v.cast<double>())) / bake.voxel_size_m);
    }
    std::sort(error_voxels.begin(), error_voxels.end());
    const double median = error_voxels[error_voxels.size() / 2];
    const double p90 = error_voxels[error_voxels.size() * 9 / 10];
    std::printf("vertex error: median %.3f voxel, p90 %.3f voxel, %zu vertices\n", median, p90,
                error_voxels.size());
    EXPECT_LT(median, kMedianBoundVoxels);
    EXPECT_LT(p90, kP90BoundVoxels);

    // Outward orientation: the sphere's triangles face away from its centre.
    int outward = 0, near_sphere = 0;
    for (const auto& t : mesh.triangles) {
        const Eigen::Vector3d a = mesh.vertices[t[0]].cast<double>(),
                              b = mesh.vertices[t[1]].cast<double>(),
                              c = mesh.vertices[t[2]].cast<double>();
        const Eigen::Vector3d centroid = (a + b + c) / 3.0;
        if (std::abs((centroid - kSphereCentre).norm() - kSphereRadiusM) > 0.05 ||
            centroid.z() < 0.3)
            continue;
        ++near_sphere;
        if ((b - a).cross(c - a).dot(centroid - kSphereCentre) > 0.0) ++outward;
    }
    ASSERT_GT(near_sphere, 100);
    EXPECT_GT(outward, kMinOutwardShare * near_sphere);
}

TEST(MapperConfig, AutomaticScheduleTakesLargeStepsAndGrowsForFinerLeaves) {
    MapperConfig config;
    EXPECT_EQ(config.iterations, -1);
    EXPECT_EQ(config.trainer.batch_size, 0);  // automatic
    BatchSchedule s = config.batch_schedule();
    EXPECT_EQ(s.batch_size, 32768);
    EXPECT_FLOAT_EQ(s.learning_rate, 0.03f);
    EXPECT_EQ(s.iterations, 250);  // default 0.2 m leaf
    EXPECT_EQ(config.batch_iterations(), 250);
    const TrainerConfig trainer = config.batch_trainer();
    EXPECT_EQ(trainer.batch_size, 32768);
    EXPECT_FLOAT_EQ(trainer.feature_adam.learning_rate, 0.03f);
    const std::pair<double, int> steps_by_leaf[] = {{0.1, 1000}, {0.3, 375}, {0.4, 500},
                                                    {0.5, 500},  {1.0, 500}, {0.001, 6250}};
    for (const auto& [leaf_m, steps] : steps_by_leaf) {
        config.octree.leaf_size_m = leaf_m;
        EXPECT_EQ(config.batch_iterations(), steps) << leaf_m << " m";
    }
    // A learning rate that is set is kept.
    config.octree.leaf_size_m = 0.2;
    config.trainer.feature_adam.learning_rate = 0.02f;
    EXPECT_FLOAT_EQ(config.batch_schedule().learning_rate, 0.02f);
    EXPECT_EQ(config.batch_schedule().batch_size, 32768);
}

TEST(MapperConfig, SettingStepsOrBatchSizeKeepsThePapersSteps) {
    MapperConfig config;
    config.iterations = 1500;  // steps set: 4096 samples at lr 0.01 unless those are set too
    BatchSchedule s = config.batch_schedule();
    EXPECT_EQ(s.batch_size, 4096);
    EXPECT_FLOAT_EQ(s.learning_rate, 0.01f);
    EXPECT_EQ(s.iterations, 1500);
    config.iterations = 0;  // explicit values are kept, 0 included
    EXPECT_EQ(config.batch_iterations(), 0);

    config.iterations = -1;
    config.trainer.batch_size = 2048;  // batch set: the paper's automatic steps
    s = config.batch_schedule();
    EXPECT_EQ(s.batch_size, 2048);
    EXPECT_FLOAT_EQ(s.learning_rate, 0.01f);
    EXPECT_EQ(s.iterations, 2400);  // default 0.2 m leaf
    config.octree.leaf_size_m = 0.1;
    EXPECT_EQ(config.batch_iterations(), 6788);
    config.octree.leaf_size_m = 1.0;
    EXPECT_EQ(config.batch_iterations(), 2400);  // coarse maps keep the default
    config.octree.leaf_size_m = 0.001;
    EXPECT_EQ(config.batch_iterations(), 50000);  // clamped
    EXPECT_EQ(config.batch_trainer().batch_size, 2048);

    // The YAML form: 0 is automatic for the batch size and the learning rate, -1 for the steps;
    // anything below is rejected, and the defaults read back as automatic.
    parse_config_yaml("training:\n  iterations: -1\n  batch_size: 0\n  learning_rate: 0\n", "test",
                      config);
    EXPECT_EQ(config.iterations, -1);
    EXPECT_EQ(config.trainer.batch_size, 0);
    EXPECT_EQ(config.trainer.feature_adam.learning_rate, 0.0f);
    EXPECT_THROW(parse_config_yaml("training:\n  iterations: -2\n", "test", config), ConfigError);
    EXPECT_THROW(parse_config_yaml("training:\n  batch_size: -1\n", "test", config), ConfigError);
    EXPECT_THROW(parse_config_yaml("training:\n  learning_rate: -0.01\n", "test", config),
                 ConfigError);
    MapperConfig read_back;
    read_back.trainer.batch_size = 77;
    parse_config_yaml(config_to_yaml(MapperConfig{}), "defaults", read_back);
    EXPECT_EQ(read_back.trainer.batch_size, 0);
    EXPECT_EQ(read_back.batch_schedule().batch_size, 32768);
}

// The automatic schedule is sized by the map's corners, or by a count the caller sets: batch
// mode's map at the refined poses takes the first phase's, so both phases train as many steps.
TEST(BatchMapperSchedule, SetCornersSizeTheAutomaticSchedule) {
    MapperConfig config = small_config();
    config.iterations = -1;
    config.trainer.batch_size = 0;  // the automatic schedule
    BatchMapper mapper(config);
    mapper.add_scan(make_scan({0, 0, 1.7}, 8, 90, 12.0));
    mapper.finish_scans();
    ASSERT_GT(mapper.sdf().octree.num_corners(), 0u);
    EXPECT_EQ(mapper.schedule_corners(), mapper.sdf().octree.num_corners());
    EXPECT_EQ(mapper.planned_iterations(), 250);  // a small map: the floor
    mapper.set_schedule_corners(3 *
                                static_cast<std::size_t>(MapperConfig::kScheduleCornersPerUnit));
    EXPECT_EQ(mapper.planned_iterations(), 750);
    mapper.set_schedule_corners(0);  // back to the map's own count
    EXPECT_EQ(mapper.planned_iterations(), 250);
}
