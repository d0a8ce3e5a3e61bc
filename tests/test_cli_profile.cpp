// `shine map --profile` through the executable: the per-stage table on stdout and the "profile"
// object of stats.json, in incremental and batch mode, on a small simulated street.
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "cli_test_support.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {
constexpr const char* kStages[] = {"load",  "preprocess", "allocate", "normals", "sample",
                                   "train", "importance", "bake",     "mesh"};

fs::path test_dir() { return test_dir_of("profile_cli"); }

CliResult run(const std::string& args) { return run_shine(args, test_dir()); }

const fs::path& street() {
    static const fs::path dir = [] {
        const fs::path d = test_dir() / "street";
        fs::remove_all(d);
        const CliResult r = run("simulate -o " + d.string() + " --frames 3 --seed 4 --no-progress");
        EXPECT_EQ(r.exit_code, 0) << r.output;
        return d;
    }();
    return dir;
}
}  // namespace

TEST(ProfileCli, IncrementalPrintsAndWritesEveryStagePerFrame) {
    const fs::path out = test_dir() / "inc";
    fs::remove_all(out);
    const CliResult r = run("map " + street().string() + " -o " + out.string() +
                            " --mode incremental --threads 2 --profile --no-eval -q");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("profile (2 threads, 3 frames)"), std::string::npos) << r.output;
    for (const char* stage : kStages) EXPECT_NE(r.output.find(stage), std::string::npos) << stage;
    const nlohmann::json profile = read_json(out / "stats.json").at("profile");
    EXPECT_EQ(profile.at("threads").get<int>(), 2);
    ASSERT_EQ(profile.at("frames").size(), 3u);
    const auto& medians = profile.at("median_seconds_per_frame_by_stage");
    const auto& totals = profile.at("total_seconds_by_stage");
    for (const char* stage : kStages) {
        EXPECT_GE(totals.at(stage).get<double>(), 0.0) << stage;
        EXPECT_GE(medians.at(stage).get<double>(), 0.0) << stage;
    }
    // Incremental mode trains and runs the importance pass in every frame; bake once.
    for (const char* stage :
         {"preprocess", "allocate", "normals", "sample", "train", "importance"}) {
        EXPECT_GT(medians.at(stage).get<double>(), 0.0) << stage;
    }
    EXPECT_EQ(medians.at("bake").get<double>(), 0.0);
    EXPECT_GT(totals.at("bake").get<double>(), 0.0);
    EXPECT_GT(profile.at("median_frame_seconds").get<double>(), 0.0);
}

TEST(ProfileCli, BatchModeWritesTheProfileWithoutTheFlag) {
    const fs::path out = test_dir() / "batch";
    fs::remove_all(out);
    const CliResult r = run("map " + street().string() + " -o " + out.string() +
                            " --iterations 20 --threads 1 --no-eval -q");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_EQ(r.output.find("profile ("), std::string::npos) << r.output;
    const nlohmann::json profile = read_json(out / "stats.json").at("profile");
    EXPECT_EQ(profile.at("threads").get<int>(), 1);
    EXPECT_EQ(profile.at("frames").size(), 3u);
    const auto& totals = profile.at("total_seconds_by_stage");
    for (const char* stage :
         {"load", "preprocess", "allocate", "normals", "sample", "train", "bake", "mesh"}) {
        EXPECT_GT(totals.at(stage).get<double>(), 0.0) << stage;
    }
    EXPECT_EQ(totals.at("importance").get<double>(), 0.0);
}
