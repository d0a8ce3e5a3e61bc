// `shine bench --speed`: four runs (the TSDF, batch, incremental, incremental without poses), each
// its own process, alternated over the rounds; the figures come from the runs' own stats.json and
// the clock around each process. Data without poses times the run without poses alone.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include "cli_test_support.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {

fs::path test_dir() { return test_dir_of("cli_bench_speed"); }

}  // namespace

TEST(BenchSpeedCli, AlternatesTheThreeMethodsAndReportsTimesAndRatios) {
    const fs::path data = test_dir() / "street";
    simulate_street(data, 3, 3);
    const fs::path config = test_dir() / "short.yaml";
    // A short consolidation as well: four incremental runs' 1000 steps took most of the test.
    std::ofstream(config) << "training:\n  iterations: 20\nincremental:\n"
                             "  iterations_per_frame: 2\n  consolidation_steps: 10\n";
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    const CliResult r = run_shine("bench --speed '" + data.string() + "' -o '" + out.string() +
                                      "' --rounds 2 --threads 1 -q -c '" + config.string() + "'",
                                  test_dir());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const auto speed = read_json(out / "speed.json");
    EXPECT_EQ(speed.at("rounds"), 2);
    for (const char* method : {"tsdf", "batch", "incremental", "no poses"}) {
        const auto& m = speed.at("methods").at(method);
        ASSERT_EQ(m.at("wall_seconds").size(), 2u) << method;
        for (const auto& s : m.at("wall_seconds")) EXPECT_GT(s.get<double>(), 0.0) << method;
        // Every run left its own products.
        std::string dir = method;
        std::replace(dir.begin(), dir.end(), ' ', '_');
        for (int round : {1, 2}) {
            EXPECT_TRUE(
                fs::exists(out / "speed" / (dir + "_" + std::to_string(round)) / "mesh.ply"))
                << method << " " << round;
        }
    }
    // Without poses: the median and the mean wall time a scan, load to end of mapping.
    EXPECT_EQ(speed.at("methods").at("no poses").at("per_scan_seconds").size(), 2u);
    EXPECT_EQ(speed.at("methods").at("no poses").at("mean_per_scan_seconds").size(), 2u);
    // Per-scan times: the TSDF's integration and incremental mode's median frame; none for batch.
    EXPECT_EQ(speed.at("methods").at("tsdf").at("per_scan_seconds").size(), 2u);
    EXPECT_EQ(speed.at("methods").at("incremental").at("per_scan_seconds").size(), 2u);
    EXPECT_TRUE(speed.at("methods").at("batch").at("per_scan_seconds").empty());
    const std::string table = read_text(out / "speed.md");
    EXPECT_NE(table.find("| incremental |"), std::string::npos) << table;
    EXPECT_NE(r.output.find("whole run / TSDF"), std::string::npos) << r.output;
}

TEST(BenchSpeedCli, DataWithoutPosesTimesTheRunWithoutPosesAlone) {
    const fs::path data = test_dir() / "street";
    simulate_street(data, 3, 3);
    fs::remove(data / "poses.txt");
    const fs::path config = test_dir() / "short.yaml";
    std::ofstream(config) << "incremental:\n  iterations_per_frame: 2\n  consolidation_steps: 10\n";
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    const CliResult r = run_shine("bench --speed '" + data.string() + "' -o '" + out.string() +
                                      "' --rounds 1 --threads 1 -q -c '" + config.string() + "'",
                                  test_dir());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const auto speed = read_json(out / "speed.json");
    ASSERT_EQ(speed.at("methods").size(), 1u);
    EXPECT_EQ(speed.at("methods").at("no poses").at("per_scan_seconds").size(), 1u);
    EXPECT_NE(read_text(out / "speed.md").find("| no poses |"), std::string::npos);
}

TEST(BenchSpeedCli, BadInputStopsBeforeAnyRun) {
    const fs::path out = test_dir() / "bad";
    fs::remove_all(out);
    CliResult r = run_shine(
        "bench --speed '" + (test_dir() / "missing").string() + "' -o '" + out.string() + "' -q",
        test_dir());
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("missing"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out / "speed.json"));
    const fs::path data = test_dir() / "street_bad";
    simulate_street(data, 2, 3);
    r = run_shine("bench --speed '" + data.string() + "' -o '" + out.string() + "' -q -c '" +
                      (test_dir() / "no_such.yaml").string() + "'",
                  test_dir());
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("no_such.yaml"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out / "speed"));
}
