// `shine eval --heldout DATA --run OUT` (cli/mapped_run.hpp): the mesh of a `shine map` run
// scored on its held-out scans as the run scored them itself, at its refined poses and deskewed
// as it deskewed, gives the run's own figures; scored at the sequence's poses it gives others;
// a run of another sequence, a damaged stats.json and --run without --heldout are refused.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "cli_test_support.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {

constexpr int kScans = 9;
constexpr int kSeed = 2;

fs::path test_dir() { return test_dir_of("cli_eval_run"); }

CliResult run(const std::string& args) { return run_shine(args, test_dir()); }

/// The street with 5 cm / 0.3 deg of pose noise, so that pose refinement moves its scans by
/// centimetres.
fs::path noisy_street() {
    const fs::path d = test_dir() / "noisy";
    fs::remove_all(d);
    const CliResult r =
        run("simulate -o '" + d.string() + "' --frames " + std::to_string(kScans) + " --seed " +
            std::to_string(kSeed) + " --no-progress --pose-noise-m 0.05 --pose-noise-deg 0.3");
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return d;
}

/// `shine map DATA -o OUT --holdout-every 3` with the YAML `config` (may be empty).
fs::path map_holding_out(const fs::path& data, const std::string& name, const std::string& config) {
    const fs::path out = test_dir() / name;
    std::string args = "map '" + data.string() + "' -o '" + out.string() +
                       "' --holdout-every 3 --threads 2 --no-eval -q";
    if (!config.empty()) {
        const fs::path yaml = test_dir() / (name + ".yaml");
        std::ofstream(yaml) << config;
        args += " -c '" + yaml.string() + "'";
    }
    const CliResult r = run(args);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return out;
}

/// `shine eval --json` of out/mesh.ply on data's every 3rd scan, with `extra` options.
nlohmann::json eval_heldout(const fs::path& data, const fs::path& out, const std::string& extra) {
    const CliResult r = run("eval --pred '" + (out / "mesh.ply").string() + "' --heldout '" +
                            data.string() + "' --holdout-every 3 --json " + extra);
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return r.exit_code == 0 ? nlohmann::json::parse(r.output) : nlohmann::json();
}

void expect_same_figures(const nlohmann::json& scored, const nlohmann::json& run_heldout) {
    ASSERT_TRUE(scored.contains("total")) << scored.dump();
    for (const char* key : {"rays", "hits", "within"}) {
        EXPECT_EQ(scored["total"][key], run_heldout["total"][key]) << key;
    }
    EXPECT_EQ(scored["total"]["median_abs_error_m"], run_heldout["total"]["median_abs_error_m"]);
}

}  // namespace

TEST(EvalRunCli, ScoresAsTheRunDidAtItsRefinedPosesAndDeskewed) {
    const fs::path data = noisy_street();
    // Simulated scans are instantaneous, so the sweep test would leave them as measured; timing
    // them from the azimuth by configuration makes the run deskew (wrongly, but as a run may),
    // which --run has to repeat to get the run's figures.
    const fs::path out = map_holding_out(data, "deskewed", "deskew:\n  azimuth_times: on\n");
    const nlohmann::json stats = read_json(out / "stats.json");
    ASSERT_TRUE(stats.contains("refine")) << "the run refined no poses";
    ASSERT_TRUE(stats["deskew"].value("active", false));
    ASSERT_TRUE(stats["deskew"].contains("sweep"));
    ASSERT_GT(stats["heldout"]["scans_deskewed"].get<int>(), 0);

    const nlohmann::json as_run = eval_heldout(data, out, "--run '" + out.string() + "'");
    expect_same_figures(as_run, stats["heldout"]);
    EXPECT_EQ(as_run["run"]["scans_deskewed"], stats["heldout"]["scans_deskewed"]);

    // At the sequence's poses, without deskewing, the same mesh scores otherwise.
    const nlohmann::json plain = eval_heldout(data, out, "");
    ASSERT_TRUE(plain.contains("total"));
    EXPECT_NE(plain["total"]["within"], stats["heldout"]["total"]["within"]);
}

TEST(EvalRunCli, ARunWithoutDeskewIsScoredAtItsRefinedPosesOnly) {
    const fs::path data = noisy_street();
    const fs::path out = map_holding_out(data, "plain", "");
    const nlohmann::json stats = read_json(out / "stats.json");
    ASSERT_FALSE(stats["deskew"].value("active", false));
    const nlohmann::json as_run = eval_heldout(data, out, "--run '" + out.string() + "'");
    expect_same_figures(as_run, stats["heldout"]);
    // The same as giving the refined poses by hand.
    const nlohmann::json by_hand =
        eval_heldout(data, out, "--poses '" + (out / "poses_refined.txt").string() + "'");
    expect_same_figures(by_hand, stats["heldout"]);
}

TEST(EvalRunCli, RefusesAnotherSequenceADamagedRunAndMisuse) {
    const fs::path data = noisy_street();
    const fs::path out = map_holding_out(data, "run", "");
    const std::string pred = "--pred '" + (out / "mesh.ply").string() + "'";

    // Another sequence: the true poses of the same scans are not the poses the run was given.
    const fs::path other = test_dir() / "other";
    fs::create_directories(other);
    fs::create_symlink(fs::absolute(data / "velodyne"), other / "velodyne");
    fs::copy_file(data / "poses_true.txt", other / "poses.txt");
    CliResult r = run("eval " + pred + " --heldout '" + other.string() +
                      "' --holdout-every 3 --run '" + out.string() + "'");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("poses_given.txt"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("other poses"), std::string::npos) << r.output;

    // Fewer scans than the run's.
    const fs::path fewer = test_dir() / "fewer";
    simulate_street(fewer, kScans - 3, kSeed);
    r = run("eval " + pred + " --heldout '" + fewer.string() + "' --holdout-every 3 --run '" +
            out.string() + "'");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("poses_refined.txt' holds 9 poses, the sequence 6 scans"),
              std::string::npos)
        << r.output;

    // A stats.json cut short, and none at all.
    const std::string text = read_text(out / "stats.json");
    std::ofstream(out / "stats.json", std::ios::trunc) << text.substr(0, text.size() / 2);
    r = run("eval " + pred + " --heldout '" + data.string() + "' --holdout-every 3 --run '" +
            out.string() + "'");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("stats.json' is not valid JSON"), std::string::npos) << r.output;
    r = run("eval " + pred + " --heldout '" + data.string() + "' --holdout-every 3 --run '" +
            (test_dir() / "missing").string() + "'");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("missing/stats.json"), std::string::npos) << r.output;

    // --run belongs to --heldout, and excludes --poses.
    r = run("eval " + pred + " --ref '" + (data / "gt_mesh.ply").string() + "' --run '" +
            out.string() + "'");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("use it with --heldout"), std::string::npos) << r.output;
    r = run("eval " + pred + " --heldout '" + data.string() + "' --holdout-every 3 --run '" +
            out.string() + "' --poses '" + (data / "poses.txt").string() + "'");
    EXPECT_NE(r.exit_code, 0);
}
