// End to end: `shine eval-revisits` on a simulated street (needs the `shine` executable built):
// the true poses agree with the direct registrations, a trajectory that jumps between two scans
// disagrees by the jump on exactly the pairs that span it, pose files of a held-out run are read,
// and a pose file of the wrong length is refused with a message naming it.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cli_test_support.hpp"
#include "shine/io/kitti.hpp"
#include "shine/odometry/se3.hpp"

namespace shine {
namespace {

using cli_test::run_shine;
using cli_test::simulate_street;
using cli_test::test_dir_of;
namespace fs = std::filesystem;

std::string quoted(const fs::path& p) { return "'" + p.string() + "'"; }

class EvalRevisitsCli : public ::testing::Test {
  protected:
    void SetUp() override {
        if (!fs::exists(SHINE_CLI_PATH)) GTEST_SKIP() << "build the shine target first";
        dir_ = test_dir_of("eval_revisits_cli");
        data_ = dir_ / "street";
        simulate_street(data_, 12, 3);
        truth_ = read_kitti_poses(data_ / "poses.txt");
    }
    fs::path dir_, data_;
    std::vector<Eigen::Isometry3d> truth_;
};

TEST_F(EvalRevisitsCli, TheTruthAgreesAndAJumpShowsOnThePairsThatSpanIt) {
    // From scan 6 on, the trajectory is moved by 12 cm sideways and turned by 0.5 degrees about
    // scan 6's position, as an odometry that slipped once would be.
    const Eigen::Vector3d pivot = truth_[6].translation();
    Eigen::Isometry3d jump = Eigen::Isometry3d::Identity();
    jump.linear() =
        Eigen::AngleAxisd(0.5 * M_PI / 180, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    jump.translation() = pivot - jump.linear() * pivot + Eigen::Vector3d(0.0, 0.12, 0.0);
    std::vector<Eigen::Isometry3d> slipped = truth_;
    for (std::size_t i = 6; i < slipped.size(); ++i) slipped[i] = jump * slipped[i];
    write_kitti_poses(dir_ / "slipped.txt", slipped);

    const auto r =
        run_shine("eval-revisits " + quoted(data_) + " " + quoted(data_ / "poses.txt") + " " +
                      quoted(dir_ / "slipped.txt") + " --min-gap 4 --max-distance-m 6 --json",
                  dir_);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const auto j = nlohmann::json::parse(r.output);
    // 1 m between scans: scan i pairs with i + 4 (4 m away), i = 0..7.
    ASSERT_EQ(j.at("pairs").get<int>(), 8);
    ASSERT_EQ(j.at("registered_pairs").get<int>(), 8);
    for (const auto& pair : j.at("per_pair")) {
        const int first = pair.at("first"), second = pair.at("second");
        EXPECT_EQ(second, first + 4);
        const auto& truth = pair.at("disagreement").at(0);
        const auto& slip = pair.at("disagreement").at(1);
        // Measured: the true poses within 0.07 cm and 0.005 degrees of the registrations.
        EXPECT_LT(truth.at("translation_m").get<double>(), 0.003) << first;
        EXPECT_LT(truth.at("rotation_deg").get<double>(), 0.02) << first;
        if (first < 6 && second >= 6) {
            // The jump seen from the pair: at least its 12 cm and its 0.5 degrees.
            EXPECT_GT(slip.at("translation_m").get<double>(), 0.11) << first;
            EXPECT_NEAR(slip.at("rotation_deg").get<double>(), 0.5, 0.02) << first;
        } else {
            EXPECT_LT(slip.at("translation_m").get<double>(), 0.003) << first;
        }
    }
    const auto& summary = j.at("trajectories");
    EXPECT_LT(summary.at(0).at("max_translation_m").get<double>(), 0.003);
    EXPECT_GT(summary.at(1).at("max_translation_m").get<double>(), 0.11);

    // The text report lists both files.
    const auto text =
        run_shine("eval-revisits " + quoted(data_) + " " + quoted(data_ / "poses.txt") + " " +
                      quoted(dir_ / "slipped.txt") + " --min-gap 4 -q",
                  dir_);
    ASSERT_EQ(text.exit_code, 0) << text.output;
    EXPECT_NE(text.output.find("8 registered"), std::string::npos) << text.output;
    EXPECT_NE(text.output.find("slipped.txt"), std::string::npos) << text.output;
}

TEST_F(EvalRevisitsCli, PoseFilesOfAHeldOutRunAndOfTheWrongLength) {
    // --holdout-every 3 maps scans 0 1 3 4 6 7 9 10: a file of those 8 poses.
    std::vector<Eigen::Isometry3d> mapped;
    for (std::size_t i = 0; i < truth_.size(); ++i) {
        if (i % 3 != 2) mapped.push_back(truth_[i]);
    }
    write_kitti_poses(dir_ / "mapped.txt", mapped);
    const auto r = run_shine("eval-revisits " + quoted(data_) + " " + quoted(dir_ / "mapped.txt") +
                                 " " + quoted(data_ / "poses.txt") +
                                 " --holdout-every 3 --min-gap 4 --max-distance-m 6 --json",
                             dir_);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    const auto j = nlohmann::json::parse(r.output);
    // Pairs among the mapped scans only, 4 or more scans apart in the sequence, each scan with
    // its nearest such partner within 6 m: 0-4, 1-6 (1-5 is held out), 3-7, 4-9, 6-10.
    std::vector<std::pair<int, int>> pairs;
    for (const auto& pair : j.at("per_pair"))
        pairs.emplace_back(pair.at("first"), pair.at("second"));
    const std::vector<std::pair<int, int>> expected = {{0, 4}, {1, 6}, {3, 7}, {4, 9}, {6, 10}};
    EXPECT_EQ(pairs, expected);
    EXPECT_EQ(j.at("registered_pairs").get<int>(), 5);

    // 8 poses without --holdout-every, and 11 poses with it: refused, naming the file.
    const auto without = run_shine(
        "eval-revisits " + quoted(data_) + " " + quoted(dir_ / "mapped.txt") + " -q", dir_);
    EXPECT_NE(without.exit_code, 0);
    EXPECT_NE(without.output.find("mapped.txt' has 8 poses for a sequence of 12 scans"),
              std::string::npos)
        << without.output;
    EXPECT_NE(without.output.find("--holdout-every"), std::string::npos) << without.output;
    std::vector<Eigen::Isometry3d> short_file(truth_.begin(), truth_.end() - 1);
    write_kitti_poses(dir_ / "short.txt", short_file);
    const auto wrong = run_shine("eval-revisits " + quoted(data_) + " " +
                                     quoted(dir_ / "short.txt") + " --holdout-every 3 -q",
                                 dir_);
    EXPECT_NE(wrong.exit_code, 0);
    EXPECT_NE(wrong.output.find("short.txt' has 11 poses"), std::string::npos) << wrong.output;
    EXPECT_NE(wrong.output.find("expected 12 (one per scan) or 8"), std::string::npos)
        << wrong.output;
}

}  // namespace
}  // namespace shine
