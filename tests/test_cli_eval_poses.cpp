// End to end: `shine eval-poses` on KITTI and TUM files written by the test (needs the `shine`
// executable built).
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "cli_test_support.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/tum.hpp"

namespace shine {
namespace {

using cli_test::run_shine;
using cli_test::test_dir_of;
namespace fs = std::filesystem;

/// A straight drive along x, 1 m between poses.
std::vector<Eigen::Isometry3d> drive(int n, double stretch) {
    std::vector<Eigen::Isometry3d> poses;
    for (int i = 0; i < n; ++i) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.translation() = Eigen::Vector3d(stretch * i, 0.0, 0.0);
        poses.push_back(T);
    }
    return poses;
}

std::string quoted(const fs::path& p) { return "'" + p.string() + "'"; }

class EvalPosesCli : public ::testing::Test {
  protected:
    void SetUp() override {
        if (!fs::exists(SHINE_CLI_PATH)) GTEST_SKIP() << "build the shine target first";
        dir_ = test_dir_of("eval_poses_cli");
    }
    fs::path dir_;
};

TEST_F(EvalPosesCli, IdenticalKittiFilesScoreZero) {
    write_kitti_poses(dir_ / "ref.txt", drive(300, 1.0));
    const auto r = run_shine(
        "eval-poses " + quoted(dir_ / "ref.txt") + " " + quoted(dir_ / "ref.txt") + " --json",
        dir_);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const auto j = nlohmann::json::parse(r.output);
    EXPECT_EQ(j.at("format"), "kitti");
    EXPECT_EQ(j.at("paired_poses"), 300);
    EXPECT_EQ(j.at("ate").at("rmse_m").get<double>(), 0.0);
    EXPECT_EQ(j.at("rpe").at("translation_percent").get<double>(), 0.0);
    EXPECT_EQ(j.at("rpe").at("per_length").size(), 2u);  // 299 m: 100 and 200 m fit
}

TEST_F(EvalPosesCli, ADriftingEstimateInTextAndJson) {
    // 2 % longer steps: every 100 m segment (101 steps, see the library test) is 2.02 m long.
    write_kitti_poses(dir_ / "ref.txt", drive(300, 1.0));
    write_kitti_poses(dir_ / "est.txt", drive(300, 1.02));
    const std::string files = quoted(dir_ / "est.txt") + " " + quoted(dir_ / "ref.txt");
    const auto j = run_shine("eval-poses " + files + " --json", dir_);
    ASSERT_EQ(j.exit_code, 0) << j.output;
    const auto json = nlohmann::json::parse(j.output);
    EXPECT_NEAR(json.at("rpe").at("per_length").at(0).at("translation_percent").get<double>(), 2.02,
                1e-9);
    EXPECT_GT(json.at("ate").at("rmse_m").get<double>(), 0.5);
    const auto sim3 = run_shine("eval-poses " + files + " --json --align sim3", dir_);
    ASSERT_EQ(sim3.exit_code, 0) << sim3.output;
    EXPECT_LT(nlohmann::json::parse(sim3.output).at("ate").at("rmse_m").get<double>(), 1e-9);
    const auto text = run_shine("eval-poses " + files, dir_);
    ASSERT_EQ(text.exit_code, 0) << text.output;
    EXPECT_NE(text.output.find("RMSE"), std::string::npos) << text.output;
    // The row of the 100 m segments: length, count, translation %.
    const std::size_t row = text.output.find("     100.0  ");
    ASSERT_NE(row, std::string::npos) << text.output;
    const std::string line = text.output.substr(row, text.output.find('\n', row) - row);
    EXPECT_NE(line.find(" 20 "), std::string::npos) << line;
    EXPECT_NE(line.find(" 2.0200 "), std::string::npos) << line;
}

TEST_F(EvalPosesCli, MismatchedLengthsNameTheFiles) {
    write_kitti_poses(dir_ / "ref.txt", drive(300, 1.0));
    write_kitti_poses(dir_ / "est_short.txt", drive(299, 1.0));
    const auto r = run_shine(
        "eval-poses " + quoted(dir_ / "est_short.txt") + " " + quoted(dir_ / "ref.txt"), dir_);
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("est_short.txt' has 299 poses"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("ref.txt' has 300"), std::string::npos) << r.output;
}

TEST_F(EvalPosesCli, MissingOrGarbledFilesNameTheFile) {
    write_kitti_poses(dir_ / "ref.txt", drive(10, 1.0));
    const auto missing = run_shine(
        "eval-poses " + quoted(dir_ / "no_such.txt") + " " + quoted(dir_ / "ref.txt"), dir_);
    EXPECT_NE(missing.exit_code, 0);
    EXPECT_NE(missing.output.find("no_such.txt"), std::string::npos) << missing.output;
    std::ofstream(dir_ / "garbled.txt") << "1 2 3 4 5\n";
    const auto garbled = run_shine(
        "eval-poses " + quoted(dir_ / "garbled.txt") + " " + quoted(dir_ / "ref.txt"), dir_);
    EXPECT_NE(garbled.exit_code, 0);
    EXPECT_NE(garbled.output.find("garbled.txt' line 1 has 5 fields"), std::string::npos)
        << garbled.output;
}

TEST_F(EvalPosesCli, TumFilesArePairedByTime) {
    std::vector<StampedPose> ref, est;
    const auto poses = drive(100, 1.0);
    for (int i = 0; i < 100; ++i) {
        ref.push_back({10.0 + 0.1 * i, poses[i]});
        // The estimate starts 2 s later and is stamped 3 ms off.
        if (i >= 20) est.push_back({10.003 + 0.1 * i, poses[i]});
    }
    write_tum_poses(dir_ / "ref.tum", ref);
    write_tum_poses(dir_ / "est.tum", est);
    const auto r = run_shine(
        "eval-poses " + quoted(dir_ / "est.tum") + " " + quoted(dir_ / "ref.tum") + " --json",
        dir_);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const auto j = nlohmann::json::parse(r.output);
    EXPECT_EQ(j.at("format"), "tum");
    EXPECT_EQ(j.at("paired_poses"), 80);
    EXPECT_LT(j.at("ate").at("rmse_m").get<double>(), 1e-9);
    const auto text =
        run_shine("eval-poses " + quoted(dir_ / "est.tum") + " " + quoted(dir_ / "ref.tum"), dir_);
    EXPECT_NE(text.output.find("paired     80 poses by timestamp"), std::string::npos)
        << text.output;
    const auto strict = run_shine("eval-poses " + quoted(dir_ / "est.tum") + " " +
                                      quoted(dir_ / "ref.tum") + " --max-time-diff-s 0.001",
                                  dir_);
    EXPECT_NE(strict.exit_code, 0);
    EXPECT_NE(strict.output.find("est.tum"), std::string::npos) << strict.output;
    const auto mixed = run_shine("eval-poses " + quoted(dir_ / "est.tum") + " " +
                                     quoted(dir_ / "ref.tum") + " --format kitti",
                                 dir_);
    EXPECT_NE(mixed.exit_code, 0);
    EXPECT_NE(mixed.output.find("est.tum"), std::string::npos) << mixed.output;
}

}  // namespace
}  // namespace shine
