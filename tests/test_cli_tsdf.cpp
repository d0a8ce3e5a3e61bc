// `shine tsdf` end to end through the executable: a small simulated street -> tsdf.vdb, mesh.ply,
// stats.json with metrics; bad input fails with a message naming the problem and no outputs.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli_test_support.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {

// Measured on this configuration (4 frames, seed 3, 0.2 m voxels, trunc 0.6 m, min weight 1):
// F-score 0.894 at 10 cm; the bound leaves room for other machines' floating-point differences.
constexpr double kMinFscore = 0.85;

fs::path test_dir() { return test_dir_of("tsdf_cli"); }

CliResult run(const std::string& args) { return run_shine(args, test_dir()); }

const char* const kOutputs[] = {"tsdf.vdb", "mesh.ply", "stats.json"};

}  // namespace

TEST(TsdfCli, SimulatedStreetGivesAnAccurateMeshAndStats) {
    const fs::path street = test_dir() / "street";
    fs::remove_all(street);
    const CliResult sim =
        run("simulate -o '" + street.string() + "' --frames 4 --seed 3 --no-progress");
    ASSERT_EQ(sim.exit_code, 0) << sim.output;

    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    const CliResult r = run("tsdf '" + street.string() + "' -o '" + out.string() +
                            "' --voxel-size-m 0.2 --trunc-m 0.6 --min-weight 1 --threads 2 -q");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("F-score"), std::string::npos) << r.output;
    for (const char* f : kOutputs) EXPECT_TRUE(fs::exists(out / f)) << f;

    std::ifstream in(out / "stats.json");
    const nlohmann::json stats = nlohmann::json::parse(in);
    EXPECT_EQ(stats.at("frames").get<int>(), 4);
    EXPECT_EQ(stats.at("parameters").at("voxel_size_m").get<double>(), 0.2);
    EXPECT_EQ(stats.at("parameters").at("trunc_m").get<double>(), 0.6);
    EXPECT_FALSE(stats.at("parameters").at("space_carving").get<bool>());
    const auto& tsdf = stats.at("tsdf");
    EXPECT_GT(tsdf.at("active_voxels").get<std::size_t>(), 10000u);
    EXPECT_EQ(tsdf.at("mem_bytes").get<std::size_t>(),
              tsdf.at("tsdf_mem_bytes").get<std::size_t>() +
                  tsdf.at("weight_mem_bytes").get<std::size_t>());
    EXPECT_EQ(tsdf.at("file_bytes").get<std::size_t>(), fs::file_size(out / "tsdf.vdb"));
    EXPECT_EQ(stats.at("mesh").at("file_bytes").get<std::size_t>(),
              fs::file_size(out / "mesh.ply"));
    for (const char* stage :
         {"read", "preprocess", "integrate", "mesh", "save", "mapping_total", "eval", "total"}) {
        EXPECT_GE(stats.at("seconds").at(stage).get<double>(), 0.0) << stage;
    }
    // The total is the whole command, the scoring included; mapping_total stops at the products.
    const auto& seconds = stats.at("seconds");
    EXPECT_GE(seconds.at("total").get<double>(),
              seconds.at("mapping_total").get<double>() + seconds.at("eval").get<double>());
    EXPECT_GT(stats.at("peak_rss_bytes").get<std::size_t>(), 0u);
    const double fscore = stats.at("eval").at("fscore").get<double>();
    std::printf("F-score at 10 cm: %.4f, TSDF %.2f MB\n", fscore,
                tsdf.at("mem_bytes").get<double>() / 1e6);
    EXPECT_GT(fscore, kMinFscore);

    // The mesh is a valid input to `shine eval`, which agrees with the stored metrics.
    const CliResult e = run("eval --pred '" + (out / "mesh.ply").string() + "' --ref '" +
                            (street / "gt_mesh.ply").string() + "' --json");
    ASSERT_EQ(e.exit_code, 0) << e.output;
    EXPECT_DOUBLE_EQ(nlohmann::json::parse(e.output).at("fscore").get<double>(), fscore);
}

TEST(TsdfCli, MissingDirectoryFailsWithItsNameAndNoOutputs) {
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    const CliResult r =
        run("tsdf '" + (test_dir() / "no_such_dir").string() + "' -o '" + out.string() + "' -q");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("no_such_dir"), std::string::npos) << r.output;
    for (const char* f : kOutputs) EXPECT_FALSE(fs::exists(out / f)) << f;
}

TEST(TsdfCli, InvalidParametersAreRejectedByName) {
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    CliResult r = run("tsdf '" + (test_dir() / "unused").string() + "' -o '" + out.string() +
                      "' --voxel-size-m -0.1 -q");
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.output.find("--voxel-size-m"), std::string::npos) << r.output;
    r = run("tsdf '" + (test_dir() / "unused").string() + "' -o '" + out.string() +
            "' --min-weight -2 -q");
    EXPECT_EQ(r.exit_code, 1);
    EXPECT_NE(r.output.find("--min-weight"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out));
}
