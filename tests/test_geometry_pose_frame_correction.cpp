// PoseFrameCorrection: a pose of a map's (refined) frame carried into the frame of the poses the
// map started from, with the corrections of the scans near it blended over a few metres.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/geometry/pose_frame_correction.hpp"

namespace {

Eigen::Isometry3d pose(double x, double y, double yaw_deg) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(yaw_deg * EIGEN_PI / 180.0, Eigen::Vector3d::UnitZ()).matrix();
    T.translation() = Eigen::Vector3d(x, y, 1.7);
    return T;
}

Eigen::Isometry3d shifted(const Eigen::Isometry3d& T, const Eigen::Vector3d& dt) {
    Eigen::Isometry3d out = T;
    out.translation() += dt;
    return out;
}

double angle_deg(const Eigen::Matrix3d& R) {
    return Eigen::AngleAxisd(R).angle() * 180.0 / EIGEN_PI;
}

}  // namespace

TEST(PoseFrameCorrection, AScansOwnRefinedPoseGoesToItsGivenPose) {
    // Scans 40 m apart (beyond the blend's reach), each corrected differently.
    std::vector<Eigen::Isometry3d> refined = {pose(0, 0, 0), pose(40, 0, 10), pose(80, 5, -20)};
    std::vector<Eigen::Isometry3d> given;
    const Eigen::Isometry3d C0 = pose(0.03, -0.02, 0.2), C1 = pose(-0.05, 0.01, -0.1);
    given.push_back(shifted(C0, Eigen::Vector3d(0, 0, -1.7)) * refined[0]);
    given.push_back(shifted(C1, Eigen::Vector3d(0, 0, -1.7)) * refined[1]);
    given.push_back(refined[2]);
    const shine::PoseFrameCorrection frame(given, refined);
    for (std::size_t k = 0; k < refined.size(); ++k) {
        const Eigen::Isometry3d out = frame.to_given(refined[k]);
        EXPECT_LT((out.translation() - given[k].translation()).norm(), 1e-9) << k;
        EXPECT_LT(angle_deg(out.linear().transpose() * given[k].linear()), 1e-7) << k;
        const Eigen::Isometry3d back = frame.to_map(given[k]);
        EXPECT_LT((back.translation() - refined[k].translation()).norm(), 1e-9) << k;
    }
}

TEST(PoseFrameCorrection, CorrectionsBlendBetweenScansAndCarryTheBodyRotation) {
    // Two scans 10 m apart, their given poses 1 cm and 3 cm above the refined ones: halfway the
    // correction is 2 cm, whatever the pose's own heading, which it keeps.
    const std::vector<Eigen::Isometry3d> refined = {pose(0, 0, 0), pose(10, 0, 0)};
    const std::vector<Eigen::Isometry3d> given = {shifted(refined[0], {0, 0, 0.01}),
                                                  shifted(refined[1], {0, 0, 0.03})};
    const shine::PoseFrameCorrection frame(given, refined);
    const Eigen::Isometry3d T = pose(5, 0, 37);
    const Eigen::Isometry3d out = frame.to_given(T);
    EXPECT_NEAR(out.translation().z() - T.translation().z(), 0.02, 1e-9);
    EXPECT_NEAR(out.translation().x(), 5.0, 1e-9);
    EXPECT_LT(angle_deg(out.linear().transpose() * T.linear()), 1e-9);
    // Nearer the first scan, nearer its correction (sigma 3 m).
    const double dz = frame.to_given(pose(2, 0, 0)).translation().z() - 1.7;
    EXPECT_GT(dz, 0.01);
    EXPECT_LT(dz, 0.02);
    // Far from both, the nearer one's correction.
    EXPECT_NEAR(frame.to_given(pose(200, 0, 0)).translation().z() - 1.7, 0.03, 1e-6);
}

TEST(PoseFrameCorrection, ARotatedFrameIsUndoneAwayFromTheOrigin) {
    // The given frame is the map's turned by 1 deg about a point 500 m away, as a gauge would be:
    // the displacement at the pose (not the correction's translation) must carry it, or the
    // lever of 500 m would put it metres off.
    Eigen::Isometry3d S = Eigen::Isometry3d::Identity();
    S.linear() = Eigen::AngleAxisd(EIGEN_PI / 180.0, Eigen::Vector3d::UnitZ()).matrix();
    S.translation() = Eigen::Vector3d(500, 0, 0) - S.linear() * Eigen::Vector3d(500, 0, 0);
    std::vector<Eigen::Isometry3d> refined, given;
    for (int k = 0; k < 20; ++k) {
        refined.push_back(pose(480 + 2.0 * k, 1.0, 5.0 * k));
        given.push_back(S * refined.back());
    }
    const shine::PoseFrameCorrection frame(given, refined);
    const Eigen::Isometry3d T = pose(501, 2, 30);
    const Eigen::Isometry3d out = frame.to_given(T);
    const Eigen::Isometry3d want = S * T;
    EXPECT_LT((out.translation() - want.translation()).norm(), 1e-6);
    EXPECT_LT(angle_deg(out.linear().transpose() * want.linear()), 1e-6);
    const Eigen::Isometry3d back = frame.to_map(out);
    EXPECT_LT((back.translation() - T.translation()).norm(), 1e-6);
}

TEST(PoseFrameCorrection, MismatchedOrEmptyInputIsRefused) {
    const std::vector<Eigen::Isometry3d> two = {pose(0, 0, 0), pose(1, 0, 0)};
    const std::vector<Eigen::Isometry3d> one = {pose(0, 0, 0)};
    EXPECT_THROW(shine::PoseFrameCorrection(two, one), shine::DataError);
    EXPECT_THROW(shine::PoseFrameCorrection({}, {}), shine::DataError);
    EXPECT_THROW(shine::PoseFrameCorrection(one, one, 0.0), shine::ConfigError);
}
