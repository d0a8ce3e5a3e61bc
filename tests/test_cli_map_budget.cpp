// `shine map --max-map-mb N` / map.max_map_mb: a map that would exceed the budget stops before
// training with a message naming the budget, the size reached, the frame and how to shrink the
// map, a non-zero exit and no output files.
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

fs::path test_dir() { return test_dir_of("cli_map_budget"); }

CliResult run(const std::string& args) { return run_shine(args, test_dir()); }

const fs::path& street() {
    static const fs::path dir = [] {
        const fs::path d = test_dir() / "street";
        fs::remove_all(d);
        const CliResult r = run("simulate -o " + d.string() + " --frames 3 --seed 3 --no-progress");
        EXPECT_EQ(r.exit_code, 0) << r.output;
        return d;
    }();
    return dir;
}

void expect_budget_failure(const CliResult& r, const fs::path& out) {
    EXPECT_NE(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("memory budget at frame 0"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("000000.bin"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("max_map_mb 1.00 MB"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("--leaf-size-m"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("float16"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("map.num_levels"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("internal error"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("Stopped before training"), std::string::npos) << r.output;
    for (const char* f : {"map.vdb", "surface.vdb", "mesh.ply", "stats.json"}) {
        EXPECT_FALSE(fs::exists(out / f)) << f << " was written despite the error";
    }
}

}  // namespace

TEST(MapBudget, FlagStopsBatchModeBeforeTraining) {
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    expect_budget_failure(
        run("map " + street().string() + " -o " + out.string() + " --max-map-mb 1 -q"), out);
}

TEST(MapBudget, ConfigKeyStopsIncrementalMode) {
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    const fs::path config = test_dir() / "budget.yaml";
    std::ofstream(config) << "map:\n  max_map_mb: 1\n";
    expect_budget_failure(run("map " + street().string() + " -o " + out.string() + " -c " +
                              config.string() + " --mode incremental -q"),
                          out);
}

TEST(MapBudget, MapWithinTheBudgetIsWrittenAndItsSizeReported) {
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    const CliResult r = run("map " + street().string() + " -o " + out.string() +
                            " --max-map-mb 500 --iterations 20 --no-eval -q");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    std::ifstream in(out / "stats.json");
    const nlohmann::json stats = nlohmann::json::parse(in);
    EXPECT_LT(stats.at("map").at("map_bytes").get<double>(), 500e6);
    EXPECT_GT(stats.at("map").at("map_bytes").get<double>(), 1e6);  // so 1 MB above must fail
}

TEST(MapBudget, NegativeBudgetIsRejected) {
    const CliResult r = run("map " + street().string() + " -o " + (test_dir() / "out").string() +
                            " --max-map-mb -5 -q");
    EXPECT_NE(r.exit_code, 0) << r.output;
    const fs::path config = test_dir() / "bad.yaml";
    std::ofstream(config) << "map:\n  max_map_mb: -1\n";
    const CliResult c = run("map " + street().string() + " -o " + (test_dir() / "out").string() +
                            " -c " + config.string() + " -q");
    EXPECT_NE(c.exit_code, 0) << c.output;
    EXPECT_NE(c.output.find("max_map_mb"), std::string::npos) << c.output;
}
