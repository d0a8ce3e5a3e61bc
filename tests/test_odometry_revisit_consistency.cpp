// Revisits: which scan pairs count, a known relative pose recovered by the direct registration of
// two scans of an analytic courtyard, a drifted trajectory's disagreement measured, and scans
// that do not overlap left unregistered.
#include <gtest/gtest.h>

#include <cmath>

#include "shine/core/error.hpp"
#include "shine/odometry/revisit_consistency.hpp"
#include "shine/odometry/se3.hpp"

using namespace shine;

namespace {

/// Points on a courtyard in the world frame, on grids of spacing `step_m` shifted by `offset_m`:
/// the ground (z = 0) and the four walls of [-15, 15] x [-10, 10] (4 m high), and two boxes that
/// pin the motion along every axis.
std::vector<Eigen::Vector3d> courtyard(double step_m, double offset_m) {
    std::vector<Eigen::Vector3d> points;
    const auto face = [&](int axis, double at, double lo_b, double hi_b, double lo_c, double hi_c) {
        const int b = (axis + 1) % 3, c = (axis + 2) % 3;
        for (double u = lo_b + offset_m; u <= hi_b; u += step_m) {
            for (double v = lo_c + offset_m; v <= hi_c; v += step_m) {
                Eigen::Vector3d p;
                p[axis] = at;
                p[b] = u;
                p[c] = v;
                points.push_back(p);
            }
        }
    };
    face(2, 0.0, -15, 15, -10, 10);  // ground: b = x, c = y
    for (const double x : {-15.0, 15.0}) face(0, x, -10, 10, 0, 4);
    for (const double y : {-10.0, 10.0}) face(1, y, 0, 4, -15, 15);  // b = z, c = x
    face(0, 4.0, -6, -3, 0, 2);                                      // a box's face across x
    face(1, 5.0, 0, 1.5, 6, 9);                                      // another's across y
    face(2, 2.0, 4, 6, -6, -3);                                      // and a top across z
    return points;
}

std::vector<Eigen::Vector3f> seen_from(const std::vector<Eigen::Vector3d>& world,
                                       const Eigen::Isometry3d& T_world_sensor) {
    std::vector<Eigen::Vector3f> out;
    const Eigen::Isometry3d T_sensor_world = T_world_sensor.inverse();
    for (const auto& p : world) out.push_back((T_sensor_world * p).cast<float>());
    return out;
}

Eigen::Isometry3d pose(double x, double y, double yaw_rad) {
    Eigen::Isometry3d T = se3_exp((Vector6d() << x, y, 1.8, 0.0, 0.0, yaw_rad).finished());
    return T;
}

}  // namespace

TEST(Revisits, EachScanPairsWithItsNearestLaterScanFarEnoughInTheSequence) {
    // A loop: out along x and back, 1 m a scan; scan numbers skip every 3rd (held out).
    std::vector<Eigen::Isometry3d> poses;
    std::vector<std::size_t> numbers;
    for (std::size_t k = 0; k < 12; ++k) {
        const double x = k < 6 ? double(k) : double(11 - k) + 0.3;
        poses.push_back(pose(x, 0.0, 0.0));
        numbers.push_back(k + k / 2);  // 0 1 3 4 6 7 9 10 ...
    }
    RevisitConfig config;
    config.min_gap_scans = 8;
    config.max_distance_m = 0.5;
    const std::vector<RevisitPair> pairs = find_revisits(poses, numbers, config);
    // Out at x = k, back at x = 11 - k + 0.3: scan k meets scan 11 - k (0.3 m away) when their
    // numbers are 8 or more apart: k = 0..3 (numbers 0,1,3,4 against 16,15,13,12).
    ASSERT_EQ(pairs.size(), 4u);
    for (std::size_t k = 0; k < 4; ++k) {
        EXPECT_EQ(pairs[k].first, k);
        EXPECT_EQ(pairs[k].second, 11 - k);
        EXPECT_NEAR(pairs[k].distance_m, 0.3, 1e-12);
    }
    config.min_gap_scans = 20;
    EXPECT_TRUE(find_revisits(poses, numbers, config).empty());
    numbers.pop_back();
    EXPECT_THROW(find_revisits(poses, numbers, config), DataError);
}

TEST(Revisits, PoseDisagreementOfHandComputedPoses) {
    Eigen::Isometry3d a = Eigen::Isometry3d::Identity();
    a.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX()).toRotationMatrix();
    a.translation() = Eigen::Vector3d(1.0, 2.0, 3.0);
    // b = a, then moved by (3, 4, 0) in a's frame and turned by 90 degrees about its z axis.
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    step.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    step.translation() = Eigen::Vector3d(3.0, 4.0, 0.0);
    const Eigen::Isometry3d b = a * step;
    const PoseDisagreement d = pose_disagreement(a, b);
    EXPECT_NEAR(d.translation_m, 5.0, 1e-9);
    EXPECT_NEAR(d.rotation_deg, 90.0, 1e-9);
    const PoseDisagreement same = pose_disagreement(b, b);
    EXPECT_NEAR(same.translation_m, 0.0, 1e-12);
    EXPECT_NEAR(same.rotation_deg, 0.0, 1e-6);
}

TEST(Revisits, DirectRegistrationRecoversTheRelativePoseAndMeasuresADrift) {
    const Eigen::Isometry3d T_world_first = pose(-3.0, -2.0, 0.2);
    const Eigen::Isometry3d T_world_second = pose(1.0, 1.5, 1.1);
    // The two scans sample the surfaces on different grids: no point is shared.
    const auto first = seen_from(courtyard(0.1, 0.0), T_world_first);
    const auto second = seen_from(courtyard(0.1, 0.047), T_world_second);
    const Eigen::Isometry3d truth = T_world_first.inverse() * T_world_second;

    // A trajectory that drifted by 0.3 m and 2 degrees between the visits starts the
    // registration; the registration finds the truth, and the drift is what it disagrees by.
    const Eigen::Isometry3d drift =
        se3_exp((Vector6d() << 0.2, -0.2, 0.1, 0.0, 0.0, 2.0 * M_PI / 180).finished());
    const Eigen::Isometry3d drifted = truth * drift;
    const RevisitRegistration r = register_revisit(first, second, drifted, RevisitConfig{});
    ASSERT_TRUE(r.accepted) << "inliers " << r.inlier_ratio;
    EXPECT_GT(r.inlier_ratio, 0.9);
    const PoseDisagreement error = pose_disagreement(r.T_first_second, truth);
    EXPECT_LT(error.translation_m, 1e-3);
    EXPECT_LT(error.rotation_deg, 0.01);
    const PoseDisagreement measured = pose_disagreement(drifted, r.T_first_second);
    const PoseDisagreement injected = pose_disagreement(drifted, truth);
    EXPECT_NEAR(measured.translation_m, injected.translation_m, 1e-3);
    EXPECT_NEAR(measured.rotation_deg, 2.0, 0.01);
}

TEST(Revisits, ScansThatDoNotOverlapAreNotRegistered) {
    const Eigen::Isometry3d T_world_first = pose(-3.0, -2.0, 0.2);
    const auto first = seen_from(courtyard(0.1, 0.0), T_world_first);
    // The second "scan" is a plane 100 m away: nothing of it lies near the first scan's surfaces.
    std::vector<Eigen::Vector3f> far;
    for (double u = 0; u < 10; u += 0.1) {
        for (double v = 0; v < 3; v += 0.1) far.emplace_back(100.0f, float(u), float(v));
    }
    RevisitConfig config;
    config.max_range_m = 200.0;
    const RevisitRegistration r =
        register_revisit(first, far, Eigen::Isometry3d::Identity(), config);
    EXPECT_FALSE(r.accepted);
    // And an empty scan is no registration either, not an error.
    EXPECT_FALSE(register_revisit(first, {}, Eigen::Isometry3d::Identity(), config).accepted);
}
