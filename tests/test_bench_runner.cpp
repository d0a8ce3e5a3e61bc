// The study's configuration: the --sizes-m parser and its errors, the per-resolution
// configurations of both methods, and the run directories.
#include <gtest/gtest.h>

#include "shine/bench/bench_runner.hpp"
#include "shine/core/error.hpp"

using namespace shine;

namespace {

/// parse_sizes_m must throw a ConfigError whose message contains `expected`.
void expect_sizes_error(const std::string& text, const std::string& expected) {
    try {
        parse_sizes_m(text);
        ADD_FAILURE() << "'" << text << "' was accepted";
    } catch (const ConfigError& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find("--sizes-m"), std::string::npos) << message;
        EXPECT_NE(message.find(expected), std::string::npos) << message;
    }
}

}  // namespace

TEST(BenchSizes, ParsesAndSortsAList) {
    EXPECT_EQ(parse_sizes_m("0.1,0.2,0.5,1.0"), (std::vector<double>{0.1, 0.2, 0.5, 1.0}));
    EXPECT_EQ(parse_sizes_m(" 1.0, 0.1 "), (std::vector<double>{0.1, 1.0}));
    EXPECT_EQ(parse_sizes_m("0.25"), (std::vector<double>{0.25}));
    EXPECT_EQ(parse_sizes_m("2"), (std::vector<double>{2.0}));
}

TEST(BenchSizes, RejectsBadLists) {
    expect_sizes_error("", "empty");
    expect_sizes_error("  ", "empty");
    expect_sizes_error("0.1,,0.2", "empty entry");
    expect_sizes_error("0.1,0.2,", "empty entry");
    expect_sizes_error("0.1;0.2", "'0.1;0.2' is not a number");
    expect_sizes_error("0.1,abc", "'abc' is not a number");
    expect_sizes_error("0.1,0.2m", "'0.2m' is not a number");
    expect_sizes_error("0", "not a positive size");
    expect_sizes_error("0.1,-0.2", "not a positive size");
    expect_sizes_error("inf", "not a positive size");
    expect_sizes_error("nan", "not a positive size");
    expect_sizes_error("0.2,0.1,0.2", "given twice");
}

TEST(BenchConfigs, ResolutionSetsLeafVoxelAndTruncation) {
    BenchConfig config;
    config.shine.iterations = 123;
    config.shine.preprocess.max_range_m = 40.0;
    config.tsdf.mesh.min_weight = 2.0;
    const MapperConfig s = shine_config_at(config, 0.5);
    EXPECT_EQ(s.octree.leaf_size_m, 0.5);
    EXPECT_EQ(s.iterations, 123);  // the rest of the configuration is kept
    const TsdfMapperConfig t = tsdf_config_at(config, 0.5);
    EXPECT_EQ(t.tsdf.voxel_size_m, 0.5);
    EXPECT_DOUBLE_EQ(t.tsdf.trunc_m, 1.5);  // 3 voxels, VDBFusion's 0.3 m at 0.1 m
    EXPECT_FALSE(t.tsdf.space_carving);
    EXPECT_EQ(t.mesh.min_weight, 2.0);
    EXPECT_EQ(t.preprocess.max_range_m, 40.0);  // both methods see the same points
    // ... each thinned with its own voxel: the TSDF fuses every 5 cm point, the mapper trains on
    // a grid of its leaf (scale-free defaults), with a surface band of at least half a leaf.
    EXPECT_EQ(t.preprocess.voxel_downsample_m, 0.05);
    EXPECT_DOUBLE_EQ(s.preprocess.voxel_downsample_m, 0.5);
    EXPECT_FLOAT_EQ(s.sampling.surface_band_m, 0.25f);
    config.tsdf.preprocess.voxel_downsample_m = 0.02;
    EXPECT_EQ(tsdf_config_at(config, 0.5).preprocess.voxel_downsample_m, 0.02);
}

TEST(BenchConfigs, RunDirectories) {
    EXPECT_EQ(bench_run_dir("out", BenchMethod::kShineVdb, 0.2),
              std::filesystem::path("out/shinevdb_0.2"));
    EXPECT_EQ(bench_run_dir("out", BenchMethod::kTsdf, 1.0), std::filesystem::path("out/tsdf_1.0"));
}

TEST(BenchMetrics, FromMeshMetrics) {
    MeshMetrics m;
    m.accuracy_m = 0.01;
    m.completion_m = 0.03;
    m.chamfer_l1_m = 0.02;
    m.completion_ratio = 0.8;
    m.precision = 0.9;
    m.fscore = 0.85;
    const BenchMetrics b = to_bench_metrics(m);
    EXPECT_EQ(b.accuracy_m, 0.01);
    EXPECT_EQ(b.completion_m, 0.03);
    EXPECT_EQ(b.chamfer_l1_m, 0.02);
    EXPECT_EQ(b.completion_ratio, 0.8);
    EXPECT_EQ(b.precision, 0.9);
    EXPECT_EQ(b.fscore, 0.85);
}
