// Motion deskew end to end: `shine simulate --motion-distortion` writes scans whose points carry
// their times, `shine map --deskew` deskews them with the given poses (and refuses scans without
// times before writing anything), and `--poses estimate` deskews on its own when times exist.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "cli_test_support.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/ply.hpp"
#include "shine/odometry/trajectory_error.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {

constexpr int kScans = 8;
constexpr double kSweepS = 0.1;

fs::path test_dir() { return test_dir_of("cli_deskew"); }

CliResult run(const std::string& args) { return run_shine(args, test_dir()); }

/// The 8-scan street with motion distortion, made once per test process.
const fs::path& distorted_street() {
    static const fs::path dir = [] {
        const fs::path d = test_dir() / "distorted";
        fs::remove_all(d);
        const CliResult r =
            run("simulate -o '" + d.string() + "' --frames " + std::to_string(kScans) +
                " --seed 1 --motion-distortion "
                "--no-progress");
        EXPECT_EQ(r.exit_code, 0) << r.output;
        return d;
    }();
    return dir;
}

std::string map_args(const fs::path& data, const fs::path& out, const std::string& extra) {
    return "map '" + data.string() + "' -o '" + out.string() + "' --threads 2 -q " + extra;
}

}  // namespace

TEST(DeskewCli, MotionDistortionWritesScansWithPointTimes) {
    const fs::path& d = distorted_street();
    EXPECT_FALSE(fs::exists(d / "velodyne" / "000000.bin"));
    for (int i = 0; i < kScans; ++i) {
        char name[32];
        std::snprintf(name, sizeof(name), "%06d.ply", i);
        const shine::TimedPoints scan = shine::read_ply_scan(d / "scans" / name);
        ASSERT_GT(scan.points_sensor.size(), 10000u) << name;
        ASSERT_EQ(scan.point_time_s.size(), scan.points_sensor.size()) << name;
        EXPECT_EQ(scan.time_format.field, "t");
        EXPECT_FALSE(scan.time_format.nanoseconds);
        EXPECT_FALSE(scan.time_format.absolute);
        for (const double t : scan.point_time_s) {
            ASSERT_GE(t, 0.0);
            ASSERT_LT(t, kSweepS);
        }
    }
    const nlohmann::json sim = read_json(d / "simulation.json");
    EXPECT_DOUBLE_EQ(sim.at("motion_distortion").at("speed_m_s").get<double>(), 10.0);
    // The poses are the undistorted simulation's: each scan's pose is its sweep's start.
    const fs::path plain = test_dir() / "plain_for_poses";
    simulate_street(plain, kScans, 1);
    EXPECT_EQ(read_text(plain / "poses.txt"), read_text(d / "poses.txt"));
    EXPECT_FALSE(sim.contains("movers"));
    EXPECT_FALSE(read_json(plain / "simulation.json").contains("motion_distortion"));
}

TEST(DeskewCli, DeskewWithoutPointTimesFailsNamingTheScanAndWritesNothing) {
    const fs::path plain = test_dir() / "plain";
    simulate_street(plain, 3, 1);
    const fs::path out = test_dir() / "no_times_out";
    fs::remove_all(out);
    const CliResult r = run(map_args(plain, out, "--deskew --no-eval"));
    EXPECT_NE(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("000000.bin' has no per-point times"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("--deskew"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out));
}

TEST(DeskewCli, GivenPosesDeskewWithTheFlagAndSayItInStats) {
    const fs::path out = test_dir() / "given";
    fs::remove_all(out);
    const CliResult r =
        run(map_args(distorted_street(), out, "--deskew --no-eval --iterations 20"));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("deskewing every scan at constant velocity between the given poses"),
              std::string::npos)
        << r.output;
    const nlohmann::json deskew = read_json(out / "stats.json").at("deskew");
    EXPECT_EQ(deskew.at("mode"), "on");
    EXPECT_TRUE(deskew.at("active").get<bool>());
    EXPECT_EQ(deskew.at("scans_deskewed").get<int>(), kScans);
    EXPECT_EQ(deskew.at("point_time").at("field"), "t");
    EXPECT_EQ(deskew.at("point_time").at("unit"), "s");
    EXPECT_EQ(deskew.at("point_time").at("reference"), "relative");
    // At 10 m/s a point measured at the end of the 0.1 s sweep moves by about 1 m.
    EXPECT_GT(deskew.at("max_shift_m").get<double>(), 0.8);

    // Without the flag the same data is mapped as measured, and stats.json says so.
    const fs::path plain_out = test_dir() / "given_no_flag";
    fs::remove_all(plain_out);
    ASSERT_EQ(run(map_args(distorted_street(), plain_out, "--no-eval --iterations 20")).exit_code,
              0);
    const nlohmann::json off = read_json(plain_out / "stats.json").at("deskew");
    EXPECT_FALSE(off.at("active").get<bool>());
    EXPECT_EQ(off.at("scans_deskewed").get<int>(), 0);
}

TEST(DeskewCli, EstimatedPosesDeskewOnTheirOwnWhenScansCarryTimes) {
    // The sweeps and their deskew are what is checked here, not the map: a short consolidation.
    const fs::path short_config = test_dir() / "short_consolidation.yaml";
    std::ofstream(short_config) << "incremental: {consolidation_steps: 100}\n";
    const std::string incremental =
        "--mode incremental --poses estimate --no-eval -c '" + short_config.string() + "'";
    const fs::path out = test_dir() / "estimated";
    fs::remove_all(out);
    const CliResult r = run(map_args(distorted_street(), out, incremental));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("between the estimated poses"), std::string::npos) << r.output;
    const nlohmann::json stats = read_json(out / "stats.json");
    const nlohmann::json& deskew = stats.at("deskew");
    EXPECT_EQ(deskew.at("mode"), "auto");
    // Scan 0 has no motion before it: its sweep comes from scan 1 (bootstrap_sweep), and every
    // scan is mapped deskewed with the sweep's estimated motion.
    EXPECT_EQ(deskew.at("scans_deskewed").get<int>(), kScans);
    EXPECT_EQ(deskew.at("scans_as_measured").get<int>(), 0);
    const nlohmann::json& scans = stats.at("odometry").at("scans");
    ASSERT_EQ(scans.size(), static_cast<std::size_t>(kScans));
    for (const nlohmann::json& scan : scans) {
        EXPECT_TRUE(scan.at("sweep_estimated").get<bool>()) << scan.dump();
        // 10 m/s forward over a 0.1 s sweep.
        EXPECT_NEAR(scan.at("sweep_twist").at(0).get<double>(), 1.0, 0.05) << scan.dump();
    }

    // Stopped after 3 scans and resumed: the replayed scans are deskewed with their recorded
    // sweeps (the first one's from the bootstrap), so the run ends as the uninterrupted one.
    const fs::path resumed = test_dir() / "estimated_resumed";
    fs::remove_all(resumed);
    const CliResult stopped =
        run(map_args(distorted_street(), resumed, incremental + " --interrupt-after 3"));
    ASSERT_EQ(stopped.exit_code, 130) << stopped.output;
    const CliResult again = run("map --resume '" + resumed.string() + "' -q --threads 2");
    ASSERT_EQ(again.exit_code, 0) << again.output;
    EXPECT_EQ(read_text(resumed / "poses.txt"), read_text(out / "poses.txt"));
    EXPECT_EQ(read_text(resumed / "mesh.ply"), read_text(out / "mesh.ply"));

    // Without the sweep's estimate scan 0 is mapped as measured, as before.
    const fs::path off = test_dir() / "estimated_no_sweep";
    fs::remove_all(off);
    const fs::path config = test_dir() / "no_sweep.yaml";
    std::ofstream(config) << "odometry: {estimate_sweep: false}\n"
                             "incremental: {consolidation_steps: 100}\n";
    const CliResult r_off =
        run(map_args(distorted_street(), off,
                     "--mode incremental --poses estimate --no-eval -c '" + config.string() + "'"));
    ASSERT_EQ(r_off.exit_code, 0) << r_off.output;
    const nlohmann::json deskew_off = read_json(off / "stats.json").at("deskew");
    EXPECT_EQ(deskew_off.at("scans_deskewed").get<int>(), kScans - 1);
    EXPECT_EQ(deskew_off.at("scans_as_measured").get<int>(), 1);
}
