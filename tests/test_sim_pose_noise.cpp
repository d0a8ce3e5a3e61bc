// The noisy poses of `shine simulate --pose-noise-m/--pose-noise-deg` (sim/pose_noise.hpp): the
// spread of many draws against the sigmas asked for, the noise recovered exactly from the poses,
// determinism per seed and per scan, the identity at zero noise, and the validation.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <string>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/sim/pose_noise.hpp"

namespace {

using shine::sim::add_pose_noise;
using shine::sim::PoseNoiseConfig;

constexpr int kDraws = 20000;
constexpr double kSigmaM = 0.05;
constexpr double kSigmaDeg = 0.3;
constexpr double kDegToRad = M_PI / 180.0;
// The sample standard deviation s of n independent normal draws has a relative standard error of
// 1 / sqrt(2 (n - 1)); the mean, sigma / sqrt(n); a correlation coefficient of independent draws,
// 1 / sqrt(n). Five standard errors: a correct implementation fails with probability < 1e-6 per
// check (and the seed is fixed, so it either passes or not), while a sigma taken per 3D norm
// instead of per axis (a factor sqrt(3)), degrees used as radians, or correlated axes fail.
constexpr double kStandardErrors = 5.0;
const double kStdRelTol = kStandardErrors / std::sqrt(2.0 * (kDraws - 1));   // 2.5 %
const double kMeanTolSigmas = kStandardErrors / std::sqrt(double(kDraws));   // 0.035 sigma
const double kCorrelationTol = kStandardErrors / std::sqrt(double(kDraws));  // 0.035
// The noise read back from a pose 5e6 m from the origin: doubles there are 1e-9 m apart.
constexpr double kRecoveredTolM = 1e-8;
constexpr double kRecoveredTolRad = 1e-12;

/// Pose i of a test trajectory: headings, pitches and rolls all over, positions up to 5e6 m from
/// the world origin (UTM-like), so the noise is checked not to depend on either.
Eigen::Isometry3d test_pose(int i) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = (Eigen::AngleAxisd(0.7 * i, Eigen::Vector3d::UnitZ()) *
                  Eigen::AngleAxisd(0.3 * std::sin(0.1 * i), Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(0.2 * std::cos(0.13 * i), Eigen::Vector3d::UnitX()))
                     .toRotationMatrix();
    T.translation() = Eigen::Vector3d(500000.0 + 3.0 * i, 5000000.0 - 1.5 * i, 0.01 * i);
    return T;
}

std::vector<Eigen::Isometry3d> test_trajectory(int n) {
    std::vector<Eigen::Isometry3d> poses;
    for (int i = 0; i < n; ++i) poses.push_back(test_pose(i));
    return poses;
}

/// The noise that takes `truth` to `noisy`: (t_noisy - t_true, log(R_noisy R_true^T)), 6-vector.
Eigen::Matrix<double, 6, 1> recovered_noise(const Eigen::Isometry3d& truth,
                                            const Eigen::Isometry3d& noisy) {
    const Eigen::AngleAxisd delta(noisy.linear() * truth.linear().transpose());
    Eigen::Matrix<double, 6, 1> v;
    v.head<3>() = noisy.translation() - truth.translation();
    v.tail<3>() = delta.angle() * delta.axis();
    return v;
}

bool same_bits(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return std::memcmp(a.matrix().data(), b.matrix().data(), sizeof(double) * 16) == 0;
}

TEST(SimPoseNoise, EmpiricalSpreadMatchesTheSigmasPerAxisIndependently) {
    const std::vector<Eigen::Isometry3d> truth = test_trajectory(kDraws);
    const PoseNoiseConfig config{kSigmaM, kSigmaDeg, 7};
    const std::vector<Eigen::Isometry3d> noisy = add_pose_noise(truth, config);
    ASSERT_EQ(noisy.size(), truth.size());

    Eigen::Matrix<double, 6, Eigen::Dynamic> noise(6, kDraws);
    for (int i = 0; i < kDraws; ++i) {
        noise.col(i) = recovered_noise(truth[i], noisy[i]);
        // The pose moved by exactly the drawn perturbation, wherever it is and however it turns.
        const shine::sim::PosePerturbation drawn = shine::sim::draw_pose_perturbation(config, i);
        ASSERT_LT((noise.col(i).head<3>() - drawn.translation_m).cwiseAbs().maxCoeff(),
                  kRecoveredTolM)
            << "scan " << i;
        ASSERT_LT((noise.col(i).tail<3>() - drawn.rotation_vector_rad).cwiseAbs().maxCoeff(),
                  kRecoveredTolRad)
            << "scan " << i;
    }
    const double sigmas[6] = {kSigmaM,
                              kSigmaM,
                              kSigmaM,
                              kSigmaDeg * kDegToRad,
                              kSigmaDeg * kDegToRad,
                              kSigmaDeg * kDegToRad};
    const Eigen::Matrix<double, 6, 1> mean = noise.rowwise().mean();
    const Eigen::MatrixXd centred = noise.colwise() - mean;
    const Eigen::Matrix<double, 6, 6> covariance = centred * centred.transpose() / (kDraws - 1);
    for (int a = 0; a < 6; ++a) {
        const double std_a = std::sqrt(covariance(a, a));
        RecordProperty("std_over_sigma_" + std::to_string(a), std::to_string(std_a / sigmas[a]));
        EXPECT_NEAR(std_a / sigmas[a], 1.0, kStdRelTol) << "component " << a;
        EXPECT_LT(std::abs(mean[a]) / sigmas[a], kMeanTolSigmas) << "component " << a;
        for (int b = a + 1; b < 6; ++b) {
            const double r = covariance(a, b) / std::sqrt(covariance(a, a) * covariance(b, b));
            EXPECT_LT(std::abs(r), kCorrelationTol) << "components " << a << ", " << b;
        }
    }
    // Independent between scans: consecutive scans' noise is uncorrelated.
    for (int a = 0; a < 6; ++a) {
        const Eigen::RowVectorXd x = centred.row(a).head(kDraws - 1);
        const Eigen::RowVectorXd y = centred.row(a).tail(kDraws - 1);
        const double r = x.dot(y) / std::sqrt(x.squaredNorm() * y.squaredNorm());
        EXPECT_LT(std::abs(r), kCorrelationTol) << "component " << a;
    }
}

TEST(SimPoseNoise, SameSeedSameNoiseAndEachScanIndependentOfTheCount) {
    const std::vector<Eigen::Isometry3d> truth = test_trajectory(20);
    const PoseNoiseConfig config{kSigmaM, kSigmaDeg, 3};
    const std::vector<Eigen::Isometry3d> a = add_pose_noise(truth, config);
    const std::vector<Eigen::Isometry3d> b = add_pose_noise(truth, config);
    const std::vector<Eigen::Isometry3d> first_five =
        add_pose_noise(std::vector<Eigen::Isometry3d>(truth.begin(), truth.begin() + 5), config);
    const std::vector<Eigen::Isometry3d> other_seed =
        add_pose_noise(truth, PoseNoiseConfig{kSigmaM, kSigmaDeg, 4});
    for (std::size_t i = 0; i < truth.size(); ++i) {
        EXPECT_TRUE(same_bits(a[i], b[i])) << "scan " << i;
        EXPECT_FALSE(same_bits(a[i], other_seed[i])) << "scan " << i;
        if (i < first_five.size()) {
            EXPECT_TRUE(same_bits(a[i], first_five[i])) << "scan " << i;
        }
    }
}

TEST(SimPoseNoise, ZeroNoiseIsTheIdentityBitForBit) {
    std::vector<Eigen::Isometry3d> truth = test_trajectory(50);
    truth[0].translation().x() = -0.0;  // even a negative zero stays
    const std::vector<Eigen::Isometry3d> same = add_pose_noise(truth, PoseNoiseConfig{0.0, 0.0, 9});
    ASSERT_EQ(same.size(), truth.size());
    for (std::size_t i = 0; i < truth.size(); ++i) {
        EXPECT_TRUE(same_bits(same[i], truth[i])) << "scan " << i;
    }
    EXPECT_FALSE(shine::sim::has_pose_noise(PoseNoiseConfig{}));
    EXPECT_TRUE(shine::sim::has_pose_noise(PoseNoiseConfig{0.0, 0.1, 1}));
}

TEST(SimPoseNoise, OneSigmaZeroLeavesThatPartExact) {
    const std::vector<Eigen::Isometry3d> truth = test_trajectory(30);
    const std::vector<Eigen::Isometry3d> rotated =
        add_pose_noise(truth, PoseNoiseConfig{0.0, kSigmaDeg, 5});
    const std::vector<Eigen::Isometry3d> moved =
        add_pose_noise(truth, PoseNoiseConfig{kSigmaM, 0.0, 5});
    for (std::size_t i = 0; i < truth.size(); ++i) {
        EXPECT_EQ(rotated[i].translation(), truth[i].translation()) << "scan " << i;
        EXPECT_NE(rotated[i].linear(), truth[i].linear()) << "scan " << i;
        EXPECT_EQ(moved[i].linear(), truth[i].linear()) << "scan " << i;
        EXPECT_NE(moved[i].translation(), truth[i].translation()) << "scan " << i;
    }
}

TEST(SimPoseNoise, NegativeOrNonFiniteSigmasAreConfigErrorsNamingTheField) {
    const double bad[] = {-0.01, std::numeric_limits<double>::quiet_NaN(),
                          std::numeric_limits<double>::infinity()};
    for (const double value : bad) {
        try {
            shine::sim::validate(PoseNoiseConfig{value, 0.0, 1});
            ADD_FAILURE() << "translation_sigma_m = " << value << " accepted";
        } catch (const shine::ConfigError& e) {
            EXPECT_NE(std::string(e.what()).find("translation_sigma_m"), std::string::npos)
                << e.what();
        }
        try {
            add_pose_noise(test_trajectory(2), PoseNoiseConfig{0.0, value, 1});
            ADD_FAILURE() << "rotation_sigma_deg = " << value << " accepted";
        } catch (const shine::ConfigError& e) {
            EXPECT_NE(std::string(e.what()).find("rotation_sigma_deg"), std::string::npos)
                << e.what();
        }
    }
}

}  // namespace
