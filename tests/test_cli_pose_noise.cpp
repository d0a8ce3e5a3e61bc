// `shine simulate --pose-noise-m/--pose-noise-deg`: the scans are the noise-free run's byte for
// byte, poses_true.txt is its poses.txt, poses.txt holds the true poses moved by the noise asked
// for (sim/pose_noise.hpp), simulation.json records it; without the options nothing changes; bad
// values are refused before anything is written.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "cli_test_support.hpp"
#include "shine/io/kitti.hpp"
#include "shine/sim/pose_noise.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {

constexpr int kScans = 5;
constexpr int kSeed = 1;
constexpr double kSigmaM = 0.05;
constexpr double kSigmaDeg = 0.3;
constexpr double kDegToRad = M_PI / 180.0;
// Five scans give 15 Gaussian draws per part (3 axes each). Their root mean square over sigma is
// sqrt(chi2_15 / 15): below 0.285 or above 1.94 with probability 1e-6 each, and any one draw
// beyond 5 sigma with probability 6e-7. The seed is fixed, so these bounds do not flake; they
// catch noise that is missing, in the wrong unit (deg as rad: x57) or on the wrong axes.
constexpr double kMinRmsOverSigma = 0.285;
constexpr double kMaxRmsOverSigma = 1.94;
constexpr double kMaxDrawSigmas = 5.0;
// `shine eval-poses` prints its ATE as a double: the same figure as computed here to rounding.
constexpr double kAteAgreementM = 1e-9;

fs::path test_dir() { return test_dir_of("cli_pose_noise"); }

CliResult run(const std::string& args) { return run_shine(args, test_dir()); }

std::string simulate_args(const fs::path& out, const std::string& extra) {
    return "simulate -o '" + out.string() + "' --frames " + std::to_string(kScans) + " --seed " +
           std::to_string(kSeed) + " --no-progress " + extra;
}

/// The street without pose noise, in the running test's directory (a street takes ~1.5 s; each
/// test makes its own, so that the tests also pass when run in one process, whose passed tests
/// remove their directories).
fs::path plain_street() {
    const fs::path d = test_dir() / "plain";
    if (!fs::exists(d / "poses.txt")) simulate_street(d, kScans, kSeed);
    return d;
}

/// The same street with pose noise of kSigmaM and kSigmaDeg, in `name` under the test's directory.
fs::path noisy_street(const std::string& name = "noisy") {
    const fs::path d = test_dir() / name;
    fs::remove_all(d);
    const CliResult r = run(simulate_args(d, "--pose-noise-m 0.05 --pose-noise-deg 0.3"));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("poses_true.txt"), std::string::npos) << r.output;
    return d;
}

std::string scan_name(int frame) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.bin", frame);
    return name;
}

}  // namespace

TEST(PoseNoiseCli, ScansAndTruthAreTheNoiseFreeRunsByteForByte) {
    const fs::path plain = plain_street();
    const fs::path noisy = noisy_street();
    EXPECT_FALSE(fs::exists(plain / "poses_true.txt"));
    ASSERT_TRUE(fs::exists(noisy / "poses_true.txt"));
    EXPECT_EQ(read_text(noisy / "poses_true.txt"), read_text(plain / "poses.txt"));
    EXPECT_NE(read_text(noisy / "poses.txt"), read_text(plain / "poses.txt"));
    for (int frame = 0; frame < kScans; ++frame) {
        const std::string scan = read_text(plain / "velodyne" / scan_name(frame));
        ASSERT_FALSE(scan.empty()) << scan_name(frame);
        EXPECT_EQ(read_text(noisy / "velodyne" / scan_name(frame)), scan) << scan_name(frame);
    }
    EXPECT_FALSE(fs::exists(noisy / "velodyne" / scan_name(kScans)));
    EXPECT_EQ(read_text(noisy / "gt_mesh.ply"), read_text(plain / "gt_mesh.ply"));

    const nlohmann::json noisy_json = read_json(noisy / "simulation.json");
    ASSERT_TRUE(noisy_json.contains("pose_noise"));
    const nlohmann::json& record = noisy_json.at("pose_noise");
    EXPECT_EQ(record.at("translation_sigma_m").get<double>(), kSigmaM);
    EXPECT_EQ(record.at("rotation_sigma_deg").get<double>(), kSigmaDeg);
    EXPECT_EQ(record.at("seed").get<int>(), kSeed);
    // Apart from the record, simulation.json is the noise-free run's.
    nlohmann::json without_record = noisy_json;
    without_record.erase("pose_noise");
    EXPECT_EQ(without_record, read_json(plain / "simulation.json"));
    EXPECT_FALSE(read_json(plain / "simulation.json").contains("pose_noise"));
}

TEST(PoseNoiseCli, NoisyPosesAreTheTruthMovedByTheNoiseAskedFor) {
    const fs::path noisy = noisy_street();
    const std::vector<Eigen::Isometry3d> truth = shine::read_kitti_poses(noisy / "poses_true.txt");
    const std::vector<Eigen::Isometry3d> poses = shine::read_kitti_poses(noisy / "poses.txt");
    ASSERT_EQ(truth.size(), static_cast<std::size_t>(kScans));
    ASSERT_EQ(poses.size(), truth.size());

    // Exactly the library's draws for this seed (%.17g round-trips doubles).
    const std::vector<Eigen::Isometry3d> expected =
        shine::sim::add_pose_noise(truth, shine::sim::PoseNoiseConfig{kSigmaM, kSigmaDeg, kSeed});
    double sum_sq_translation_m2 = 0.0;
    double sum_sq_rotation_rad2 = 0.0;
    for (int i = 0; i < kScans; ++i) {
        EXPECT_EQ(poses[i].matrix(), expected[i].matrix()) << "scan " << i;
        const Eigen::Vector3d dt = poses[i].translation() - truth[i].translation();
        const Eigen::AngleAxisd dR(poses[i].linear() * truth[i].linear().transpose());
        const Eigen::Vector3d dphi = dR.angle() * dR.axis();
        EXPECT_LT(dt.cwiseAbs().maxCoeff(), kMaxDrawSigmas * kSigmaM) << "scan " << i;
        EXPECT_LT(dphi.cwiseAbs().maxCoeff(), kMaxDrawSigmas * kSigmaDeg * kDegToRad)
            << "scan " << i;
        EXPECT_GT(dt.norm(), 0.0) << "scan " << i << ": every scan is perturbed, the first too";
        EXPECT_GT(dphi.norm(), 0.0) << "scan " << i;
        sum_sq_translation_m2 += dt.squaredNorm();
        sum_sq_rotation_rad2 += dphi.squaredNorm();
    }
    const double rms_translation_m = std::sqrt(sum_sq_translation_m2 / (3 * kScans));
    const double rms_rotation_rad = std::sqrt(sum_sq_rotation_rad2 / (3 * kScans));
    EXPECT_GT(rms_translation_m / kSigmaM, kMinRmsOverSigma);
    EXPECT_LT(rms_translation_m / kSigmaM, kMaxRmsOverSigma);
    EXPECT_GT(rms_rotation_rad / (kSigmaDeg * kDegToRad), kMinRmsOverSigma);
    EXPECT_LT(rms_rotation_rad / (kSigmaDeg * kDegToRad), kMaxRmsOverSigma);

    // The scoring tool sees the same error: its unaligned ATE is the positions' RMS error.
    const CliResult r = run("eval-poses '" + (noisy / "poses.txt").string() + "' '" +
                            (noisy / "poses_true.txt").string() + "' --align none --json");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const double ate_rmse_m = nlohmann::json::parse(r.output).at("ate").at("rmse_m").get<double>();
    EXPECT_NEAR(ate_rmse_m, std::sqrt(sum_sq_translation_m2 / kScans), kAteAgreementM);
}

TEST(PoseNoiseCli, SameSeedSamePosesAndNoNoiseRemovesAStaleTruth) {
    const fs::path d = noisy_street("rerun");
    EXPECT_EQ(read_text(d / "poses.txt"), read_text(noisy_street() / "poses.txt"));
    // A run without noise in the same directory: its poses are the truth, none is left beside.
    const CliResult r = run(simulate_args(d, "--pose-noise-m 0 --pose-noise-deg 0"));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_FALSE(fs::exists(d / "poses_true.txt"));
    for (const char* file : {"poses.txt", "simulation.json", "README.txt"}) {
        EXPECT_EQ(read_text(d / file), read_text(plain_street() / file)) << file;
    }
}

TEST(PoseNoiseCli, NegativeOrNonFiniteNoiseIsRefusedNamingTheFlag) {
    const struct {
        const char* args;
        const char* flag;
    } cases[] = {{"--pose-noise-m -0.1", "--pose-noise-m"},
                 {"--pose-noise-m inf", "--pose-noise-m"},
                 {"--pose-noise-deg nan", "--pose-noise-deg"},
                 {"--pose-noise-deg -1", "--pose-noise-deg"}};
    for (const auto& c : cases) {
        const fs::path d = test_dir() / "refused";
        fs::remove_all(d);
        const CliResult r = run(simulate_args(d, c.args));
        EXPECT_NE(r.exit_code, 0) << c.args;
        EXPECT_NE(r.output.find(std::string(c.flag) + " = "), std::string::npos) << r.output;
        EXPECT_NE(r.output.find("must be a finite number >= 0"), std::string::npos) << r.output;
        EXPECT_FALSE(fs::exists(d)) << c.args << ": nothing may be written";
    }
}
