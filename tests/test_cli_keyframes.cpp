// Tracking decoupled from mapping (keyframe_policy.hpp) end to end, `shine map --mode incremental`
// without poses on a simulated street: keyframes that are every scan reproduce the run that
// trains every scan, deferred scans are caught up and counted, and a budget is kept on a run whose
// training is slowed down.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <string>
#include <vector>

#include "cli_test_support.hpp"
#include "shine/io/kitti.hpp"
#include "shine/odometry/trajectory_error.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {

fs::path test_dir() { return test_dir_of("cli_keyframes"); }

CliResult run(const std::string& args) { return run_shine(args, test_dir()); }

/// A street of `scans` scans (1 m apart), made once per count.
fs::path street(int scans) {
    const fs::path d =
        fs::path(SHINE_TEST_TMP_DIR) / "cli_keyframes_data" / ("street_" + std::to_string(scans));
    if (!fs::exists(d / "poses.txt")) {
        fs::create_directories(d.parent_path());
        simulate_street(d, scans, 1);
    }
    return d;
}

fs::path write_config(const std::string& name, const std::string& yaml) {
    const fs::path path = test_dir() / (name + ".yaml");
    std::ofstream(path) << yaml;
    return path;
}

CliResult map(const fs::path& data, const fs::path& out, const fs::path& config,
              const std::string& extra_args = "") {
    fs::remove_all(out);
    return run("map '" + data.string() + "' -o '" + out.string() +
               "' --mode incremental --poses estimate --threads 2 -q --no-eval -c '" +
               config.string() + "' " + extra_args);
}

/// The mean of the scans' wall_seconds from `first` on (stats.json odometry.scans).
double mean_wall_seconds_from(const nlohmann::json& scans, std::size_t first) {
    double sum = 0.0;
    for (std::size_t i = first; i < scans.size(); ++i)
        sum += scans[i].at("wall_seconds").get<double>();
    return sum / static_cast<double>(scans.size() - first);
}

int trained_from(const nlohmann::json& scans, std::size_t first) {
    int n = 0;
    for (std::size_t i = first; i < scans.size(); ++i) n += scans[i].at("trained").get<bool>();
    return n;
}

constexpr std::size_t kWarmupScans = 4;  // the first scan and odometry.icp_warmup_scans = 3

}  // namespace

TEST(KeyframesCli, KeyframesThatAreEveryScanReproduceTrainingEveryScan) {
    const fs::path data = street(8);
    const fs::path all = test_dir() / "all";
    const fs::path every = test_dir() / "every";
    const CliResult a = map(data, all, write_config("off", "keyframes:\n  enabled: false\n"));
    ASSERT_EQ(a.exit_code, 0) << a.output;
    const CliResult b =
        map(data, every, write_config("every", "keyframes:\n  min_translation_m: 0.000001\n"));
    ASSERT_EQ(b.exit_code, 0) << b.output;
    EXPECT_EQ(read_text(every / "poses.txt"), read_text(all / "poses.txt"));
    EXPECT_EQ(read_text(every / "mesh.ply"), read_text(all / "mesh.ply"));
    const nlohmann::json k = read_json(every / "stats.json").at("keyframes");
    EXPECT_EQ(k.at("trained").get<int>(), 8);
    EXPECT_EQ(k.at("deferred").get<int>(), 0);
    EXPECT_FALSE(read_json(all / "stats.json").at("keyframes").at("enabled").get<bool>());
}

TEST(KeyframesCli, DeferredScansAreCaughtUpCountedAndTracked) {
    const fs::path data = street(12);
    const fs::path out = test_dir() / "defaults";
    const CliResult r = map(data, out, write_config("defaults", "{}\n"));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const nlohmann::json stats = read_json(out / "stats.json");
    const nlohmann::json& k = stats.at("keyframes");
    const nlohmann::json& scans = stats.at("odometry").at("scans");
    ASSERT_EQ(scans.size(), 12u);
    const int trained = k.at("trained").get<int>();
    const int deferred = k.at("deferred").get<int>();
    EXPECT_EQ(trained + deferred, 12);
    // 1 m between scans, a keyframe every 4 m: scans 4-6 and 8-10 wait.
    EXPECT_EQ(deferred, 6);
    EXPECT_EQ(trained_from(scans, 0), trained);
    EXPECT_EQ(k.at("caught_up").get<int>(), deferred);
    EXPECT_EQ(k.at("skipped").get<int>(), 0);
    // Every scan is in the map: the deferred ones integrated after the last scan, and their
    // steps added to the consolidation.
    EXPECT_EQ(stats.at("frames").get<int>(), 12);
    EXPECT_NE(r.output.find("6 deferred"), std::string::npos) << r.output;
    const auto estimate = shine::read_kitti_poses(out / "poses.txt");
    const auto truth = shine::read_kitti_poses(data / "poses.txt");
    // Measured 0.9 mm (ATE RMSE, SE(3)-aligned) on this street, as when every scan trains.
    EXPECT_LT(
        shine::absolute_trajectory_error(estimate, truth, shine::TrajectoryAlignment::kSe3).rmse_m,
        0.005);
}

TEST(KeyframesCli, KeyframesTakeTheStepsOfTheScansDeferredBeforeThem) {
    // Scans 0-8 of a turning street: keyframes 0-3 and 6 (the map covers too little of it), 4,
    // 5, 7 and 8 deferred as redundant. Keyframe 6 trains the steps of three scans (itself, 4
    // and 5); no keyframe comes after 7 and 8. A backlog of 2 drops 4 and 5 and keeps 7 and 8,
    // which the consolidation integrates and takes the steps of.
    const fs::path data = street(11);
    const fs::path out = test_dir() / "deferred_steps";
    const CliResult r = map(data, out,
                            write_config("deferred_steps",
                                         "incremental:\n  consolidation_steps: 20\nkeyframes:\n"
                                         "  max_deferred_scans: 2\n"),
                            "--last-frame 8");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const nlohmann::json stats = read_json(out / "stats.json");
    const nlohmann::json& k = stats.at("keyframes");
    std::vector<std::string> reasons;
    for (const auto& s : stats.at("odometry").at("scans"))
        reasons.push_back(s.at("keyframe_reason").get<std::string>());
    ASSERT_EQ(reasons,
              (std::vector<std::string>{"first", "warm-up", "warm-up", "warm-up", "redundant",
                                        "redundant", "coverage", "redundant", "redundant"}));
    EXPECT_TRUE(k.at("keyframe_takes_deferred_steps").get<bool>());
    EXPECT_EQ(k.at("deferred").get<int>(), 4);
    EXPECT_EQ(k.at("skipped").get<int>(), 2);
    EXPECT_EQ(k.at("caught_up").get<int>(), 2);
    EXPECT_EQ(k.at("deferred_steps_taken").get<int>(), 2);
    const int per_scan = stats.at("incremental").at("iterations_per_frame").get<int>();
    const int consolidation = stats.at("incremental").at("consolidation").at("steps").get<int>();
    EXPECT_EQ(consolidation, 20 + 2 * per_scan);
    EXPECT_EQ(stats.at("iterations").get<int>() - consolidation, (4 + 3) * per_scan);
    EXPECT_NE(r.output.find("the keyframes took the steps of 2"), std::string::npos) << r.output;
}

TEST(KeyframesCli, BudgetIsKeptWhenTrainingIsSlow) {
    // Each trained scan made 600 ms slower; keyframes every 2nd scan. Without a budget the scans
    // after the warm-up take more than 300 ms on average; with a 300 ms budget the keyframes
    // train in the background, each scan gives the training what is left of its 300 ms, and the
    // keyframes that come while one trains are deferred.
    const fs::path data = street(20);
    const std::string base =
        "incremental:\n  consolidation_steps: 20\nkeyframes:\n"
        "  max_interval_scans: 2\n";
    ASSERT_EQ(setenv("SHINE_TEST_TRAINING_DELAY_MS", "600", 1), 0);
    const fs::path free_run = test_dir() / "no_budget";
    const CliResult a = map(data, free_run, write_config("no_budget", base));
    const fs::path kept = test_dir() / "budget";
    const CliResult b = map(data, kept, write_config("budget", base + "  max_ms_per_scan: 300\n"));
    unsetenv("SHINE_TEST_TRAINING_DELAY_MS");
    ASSERT_EQ(a.exit_code, 0) << a.output;
    ASSERT_EQ(b.exit_code, 0) << b.output;
    const nlohmann::json free_stats = read_json(free_run / "stats.json");
    const nlohmann::json kept_stats = read_json(kept / "stats.json");
    const nlohmann::json& free_scans = free_stats.at("odometry").at("scans");
    const nlohmann::json& kept_scans = kept_stats.at("odometry").at("scans");
    EXPECT_GT(mean_wall_seconds_from(free_scans, kWarmupScans), 0.3);
    EXPECT_LT(mean_wall_seconds_from(kept_scans, kWarmupScans), 0.3 * 1.1);
    EXPECT_GT(kept_stats.at("keyframes").at("deferred_while_busy").get<int>(), 0);
    EXPECT_GE(trained_from(kept_scans, kWarmupScans), 1);
    EXPECT_EQ(kept_stats.at("keyframes").at("caught_up").get<int>(),
              kept_stats.at("keyframes").at("deferred").get<int>());
    // Registration is never what the budget skips: every scan has its pose.
    for (const auto& s : kept_scans) EXPECT_NE(s.at("method"), "skipped");
}

TEST(KeyframesCli, BackgroundTrainingNeverMakesRegistrationWait) {
    // With a budget the keyframes train on their own thread: with each training made a second
    // slower and a 200 ms budget, no scan's wall time (load to the end of its turn) comes near
    // that second, the keyframes that come while a training runs are deferred, some later ones
    // train, and every scan still ends up in the map.
    const fs::path data = street(16);
    ASSERT_EQ(setenv("SHINE_TEST_TRAINING_DELAY_MS", "1000", 1), 0);
    const fs::path out = test_dir() / "background";
    const CliResult r = map(data, out,
                            write_config("background",
                                         "incremental:\n  consolidation_steps: 20\nkeyframes:\n"
                                         "  max_interval_scans: 1\n  max_ms_per_scan: 200\n"));
    unsetenv("SHINE_TEST_TRAINING_DELAY_MS");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const nlohmann::json stats = read_json(out / "stats.json");
    const nlohmann::json& k = stats.at("keyframes");
    EXPECT_TRUE(k.at("background_training").get<bool>());
    const nlohmann::json& scans = stats.at("odometry").at("scans");
    ASSERT_EQ(scans.size(), 16u);
    for (const auto& s : scans) EXPECT_LT(s.at("wall_seconds").get<double>(), 0.5) << s.dump();
    EXPECT_GT(k.at("deferred_while_busy").get<int>(), 0);
    EXPECT_GE(k.at("trained").get<int>(), 2);
    EXPECT_EQ(k.at("trained").get<int>() + k.at("caught_up").get<int>(), 16);
    EXPECT_EQ(stats.at("frames").get<int>(), 16);
}
