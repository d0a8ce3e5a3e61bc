// Trajectory errors on hand-computed cases: rigid and similarity copies align to zero, offsets of
// known lengths, a constant scale drift and a constant heading drift give the expected relative
// errors, short sequences fall back to fractions of their length; pairing by timestamps.
#include <gtest/gtest.h>

#include <cmath>

#include "shine/core/error.hpp"
#include "shine/odometry/pose_association.hpp"
#include "shine/odometry/se3.hpp"
#include "shine/odometry/trajectory_error.hpp"

using namespace shine;

namespace {

constexpr double kExactTol = 1e-9;  // m, %, deg/100 m: double rounding over 1000 poses

/// A winding, climbing path of `n` poses (1 m apart roughly), heading along the path.
std::vector<Eigen::Isometry3d> winding_path(int n) {
    std::vector<Eigen::Isometry3d> poses;
    for (int i = 0; i < n; ++i) {
        const double s = i * 0.05;
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.translation() =
            Eigen::Vector3d(20 * std::sin(s), 20 * (1 - std::cos(s)) + 3 * s, 0.5 * s);
        T.linear() = Eigen::AngleAxisd(s, Eigen::Vector3d::UnitZ()).toRotationMatrix();
        poses.push_back(T);
    }
    return poses;
}

/// A straight line along x with 1 m between poses.
std::vector<Eigen::Isometry3d> straight_line(int n) {
    std::vector<Eigen::Isometry3d> poses;
    for (int i = 0; i < n; ++i) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.translation().x() = i;
        poses.push_back(T);
    }
    return poses;
}

}  // namespace

TEST(AbsoluteTrajectoryError, ARigidCopyAlignsToZeroButNotWithoutAlignment) {
    const auto reference = winding_path(200);
    const Eigen::Isometry3d G = se3_exp((Vector6d() << 10, -5, 2, 0.1, -0.2, 1.0).finished());
    std::vector<Eigen::Isometry3d> estimate;
    for (const auto& T : reference) estimate.push_back(G * T);
    const auto ate = absolute_trajectory_error(estimate, reference, TrajectoryAlignment::kSe3);
    EXPECT_EQ(ate.num_poses, 200u);
    EXPECT_LT(ate.rmse_m, kExactTol);
    EXPECT_LT(ate.max_m, kExactTol);
    EXPECT_LT((ate.estimate_to_reference.R - G.linear().transpose()).norm(), kExactTol);
    const auto raw = absolute_trajectory_error(estimate, reference, TrajectoryAlignment::kNone);
    EXPECT_GT(raw.rmse_m, 5.0);
}

TEST(AbsoluteTrajectoryError, ASimilarityCopyNeedsSim3AndGivesBackTheScale) {
    const auto reference = winding_path(200);
    const Eigen::Isometry3d G = se3_exp((Vector6d() << 1, 2, 3, 0.3, 0.1, -0.5).finished());
    const double scale = 0.5;
    std::vector<Eigen::Isometry3d> estimate;
    for (const auto& T : reference) {
        Eigen::Isometry3d E = G * T;
        E.translation() *= scale;
        estimate.push_back(E);
    }
    const auto sim3 = absolute_trajectory_error(estimate, reference, TrajectoryAlignment::kSim3);
    EXPECT_LT(sim3.rmse_m, kExactTol);
    EXPECT_NEAR(sim3.estimate_to_reference.scale, 1.0 / scale, kExactTol);
    const auto se3 = absolute_trajectory_error(estimate, reference, TrajectoryAlignment::kSe3);
    EXPECT_GT(se3.rmse_m, 1.0);
}

TEST(AbsoluteTrajectoryError, StatisticsOfKnownOffsets) {
    // Offsets of length 1, 2, 3, 4 m (no alignment): RMSE sqrt(30 / 4), mean and median 2.5.
    const auto reference = straight_line(4);
    auto estimate = reference;
    estimate[0].translation() += Eigen::Vector3d(0, 1, 0);
    estimate[1].translation() += Eigen::Vector3d(0, 0, 2);
    estimate[2].translation() += Eigen::Vector3d(0, -3, 0);
    estimate[3].translation() += Eigen::Vector3d(0, 0, -4);
    const auto ate = absolute_trajectory_error(estimate, reference, TrajectoryAlignment::kNone);
    EXPECT_NEAR(ate.rmse_m, std::sqrt(30.0 / 4.0), kExactTol);
    EXPECT_NEAR(ate.mean_m, 2.5, kExactTol);
    EXPECT_NEAR(ate.median_m, 2.5, kExactTol);
    EXPECT_NEAR(ate.max_m, 4.0, kExactTol);
}

TEST(RelativePoseError, AOnePercentScaleDriftOnAStraightLine) {
    // Poses 1 m apart over 999 m; the estimate stretches every step by 1 %. A segment of length
    // L from frame i ends at the first frame whose distance exceeds d_i + L, frame i + L + 1, so
    // its error is 0.01 (L + 1) m: (L + 1) / L % for every segment of that length.
    const auto reference = straight_line(1000);
    auto estimate = reference;
    for (auto& T : estimate) T.translation() *= 1.01;
    const RelativePoseError rpe = relative_pose_error(estimate, reference);
    EXPECT_TRUE(rpe.kitti_lengths);
    EXPECT_DOUBLE_EQ(rpe.path_length_m, 999.0);
    ASSERT_EQ(rpe.per_length.size(), 8u);
    double weighted = 0.0;
    std::size_t total = 0;
    for (std::size_t k = 0; k < 8; ++k) {
        const RelativeErrorOfLength& row = rpe.per_length[k];
        const double L = 100.0 * double(k + 1);
        EXPECT_EQ(row.length_m, L);
        // First frames 0, 10, ... up to 998 - L.
        EXPECT_EQ(row.num_segments, std::size_t((998 - int(L)) / 10 + 1)) << L;
        EXPECT_NEAR(row.translation_percent, (L + 1) / L, kExactTol) << L;
        EXPECT_NEAR(row.rotation_deg_per_100m, 0.0, kExactTol);
        weighted += row.translation_percent * double(row.num_segments);
        total += row.num_segments;
    }
    EXPECT_EQ(rpe.num_segments, total);
    EXPECT_NEAR(rpe.translation_percent, weighted / double(total), kExactTol);
}

TEST(RelativePoseError, AConstantHeadingDriftGivesItsDegreesPer100M) {
    // The estimate turns by 0.01 deg per frame in place: a segment of length L spans L + 1 frames
    // (see above), so its rotation error is 0.01 (L + 1) deg, i.e. (L + 1) / L deg / 100 m.
    const auto reference = straight_line(1000);
    auto estimate = reference;
    const double per_frame_rad = 0.01 * M_PI / 180.0;
    for (std::size_t i = 0; i < estimate.size(); ++i) {
        estimate[i].linear() =
            Eigen::AngleAxisd(per_frame_rad * double(i), Eigen::Vector3d::UnitZ())
                .toRotationMatrix();
    }
    const RelativePoseError rpe = relative_pose_error(estimate, reference);
    for (const auto& row : rpe.per_length) {
        EXPECT_NEAR(row.rotation_deg_per_100m, (row.length_m + 1) / row.length_m, 1e-7)
            << row.length_m;
        EXPECT_GT(row.translation_percent, 0.0);  // a rotated frame sees the step sideways
    }
}

TEST(RelativePoseError, AShortSequenceIsScoredOnFractionsOfItsLength) {
    const auto reference = straight_line(51);  // 50 m: no KITTI length fits
    auto estimate = reference;
    for (auto& T : estimate) T.translation() *= 1.02;
    const RelativePoseError rpe = relative_pose_error(estimate, reference);
    EXPECT_FALSE(rpe.kitti_lengths);
    ASSERT_EQ(rpe.per_length.size(), 8u);
    EXPECT_DOUBLE_EQ(rpe.per_length[0].length_m, 5.0);
    EXPECT_DOUBLE_EQ(rpe.per_length[7].length_m, 40.0);
    // L = 5 m: segments end at i + 6, error 0.02 * 6 m over 5 m = 2.4 %.
    EXPECT_NEAR(rpe.per_length[0].translation_percent, 2.4, kExactTol);
    // A 250 m path scores 100 and 200 m only.
    const RelativePoseError mid = relative_pose_error(straight_line(251), straight_line(251));
    EXPECT_TRUE(mid.kitti_lengths);
    ASSERT_EQ(mid.per_length.size(), 2u);
    EXPECT_EQ(mid.translation_percent, 0.0);
}

TEST(TrajectoryError, BadInputIsADataError) {
    const auto a = straight_line(10), b = straight_line(11);
    EXPECT_THROW(absolute_trajectory_error(a, b, TrajectoryAlignment::kSe3), DataError);
    EXPECT_THROW(relative_pose_error(a, b), DataError);
    EXPECT_THROW(
        absolute_trajectory_error(straight_line(2), straight_line(2), TrajectoryAlignment::kNone),
        DataError);
    const std::vector<Eigen::Isometry3d> still(5, Eigen::Isometry3d::Identity());
    EXPECT_THROW(absolute_trajectory_error(still, straight_line(5), TrajectoryAlignment::kSe3),
                 DataError);
    EXPECT_THROW(relative_pose_error(straight_line(5), still), DataError);  // reference still
    EXPECT_THROW(parse_trajectory_alignment("affine", "--align"), ConfigError);
    try {
        absolute_trajectory_error(a, b, TrajectoryAlignment::kSe3);
    } catch (const DataError& e) {
        EXPECT_NE(std::string(e.what()).find("10 poses and the reference 11"), std::string::npos)
            << e.what();
    }
}

TEST(PoseAssociation, PairsNearestTimesWithinTheTolerance) {
    std::vector<StampedPose> est, ref;
    for (int i = 0; i < 10; ++i) ref.push_back({0.1 * i, Eigen::Isometry3d::Identity()});
    // 0.004 s late; one far from any reference time; two estimates nearest to reference 5.
    for (const double t : {0.004, 0.104, 0.25, 0.498, 0.503, 0.904}) {
        est.push_back({t, Eigen::Isometry3d::Identity()});
    }
    const PosePairs pairs = associate_by_time(est, ref, 0.01, "est.txt", "ref.txt");
    const PosePairs expected = {{0, 0}, {1, 1}, {3, 5}, {5, 9}};
    EXPECT_EQ(pairs, expected);
    std::swap(est[0], est[1]);
    try {
        associate_by_time(est, ref, 0.01, "est.txt", "ref.txt");
        ADD_FAILURE() << "unsorted times were accepted";
    } catch (const DataError& e) {
        EXPECT_NE(std::string(e.what()).find("est.txt"), std::string::npos) << e.what();
    }
}
