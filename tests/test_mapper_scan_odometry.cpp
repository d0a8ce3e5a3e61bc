// The odometry while mapping (scan_odometry.hpp): the first scan anchors the world, a warm-up scan
// is registered by ICP to the scans before it (a known motion recovered in an analytic room), a
// scan without points is skipped at the prediction, the records survive a checkpoint, and the
// odometry section of the configuration is parsed and checked.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <tuple>

#include "shine/core/error.hpp"
#include "shine/io/binary_stream.hpp"
#include "shine/mapper/mapper_config.hpp"
#include "shine/mapper/scan_odometry.hpp"
#include "shine/odometry/scan_deskew.hpp"
#include "shine/odometry/se3.hpp"

using namespace shine;

namespace {

constexpr double kTranslationTolM = 0.01;  // 1 cm
constexpr double kRotationTolRad = 1e-3;   // 0.06 deg

/// Points on the surfaces of a 20 x 16 x 6 m room with two pillars, 0.1 m apart (world frame).
std::vector<Eigen::Vector3d> room_world() {
    std::vector<Eigen::Vector3d> points;
    const double step = 0.1;
    for (double x = -10; x <= 10; x += step) {
        for (double y = -8; y <= 8; y += step) {
            points.emplace_back(x, y, -2.0);  // floor
        }
        for (double z = -2; z <= 4; z += step) {
            points.emplace_back(x, -8.0, z);  // side walls
            points.emplace_back(x, 8.0, z);
        }
    }
    for (double y = -8; y <= 8; y += step) {
        for (double z = -2; z <= 4; z += step) {
            points.emplace_back(-10.0, y, z);  // end walls
            points.emplace_back(10.0, y, z);
        }
    }
    // Pillars (1 m square) at (3, 2) and (-4, -3): they fix the translation along the walls.
    for (const Eigen::Vector2d& c : {Eigen::Vector2d(3, 2), Eigen::Vector2d(-4, -3)}) {
        for (double s = -0.5; s <= 0.5; s += step) {
            for (double z = -2; z <= 4; z += step) {
                points.emplace_back(c.x() + s, c.y() - 0.5, z);
                points.emplace_back(c.x() + s, c.y() + 0.5, z);
                points.emplace_back(c.x() - 0.5, c.y() + s, z);
                points.emplace_back(c.x() + 0.5, c.y() + s, z);
            }
        }
    }
    return points;
}

/// The room seen from the sensor at T_world_sensor (every surface point, in the sensor frame).
Scan room_scan(const Eigen::Isometry3d& T_world_sensor) {
    Scan scan;
    const Eigen::Isometry3d T_sensor_world = T_world_sensor.inverse();
    for (const Eigen::Vector3d& p : room_world()) {
        scan.points_sensor.push_back((T_sensor_world * p).cast<float>());
    }
    scan.source = "room";
    return scan;
}

/// The room measured during a 0.1 s sweep from T_world_sensor while the sensor moves by
/// `sweep_twist` over the sweep: each point at the fraction of the sweep its azimuth gives, in
/// the sensor frame at its time, which the scan carries (seconds after the pose).
Scan swept_room_scan(const Eigen::Isometry3d& T_world_sensor, const Vector6d& sweep_twist) {
    Scan scan;
    const Eigen::Isometry3d T_sensor_world = T_world_sensor.inverse();
    for (const Eigen::Vector3d& x : room_world()) {
        const Eigen::Vector3d p = T_sensor_world * x;
        const double s = (std::atan2(p.y(), p.x()) + M_PI) / (2.0 * M_PI);
        scan.points_sensor.push_back((se3_exp(s * sweep_twist).inverse() * p).cast<float>());
        scan.point_time_s.push_back(0.1 * s);
    }
    scan.source = "swept room";
    return scan;
}

NeuralSdf empty_map() { return NeuralSdf(FeatureOctreeConfig{}, DecoderConfig{}); }

}  // namespace

TEST(ScanOdometry, FirstScanIsTheWorldAndWarmUpScansRegisterByIcp) {
    OdometryConfig config;
    config.icp_warmup_scans = 3;
    ScanOdometry odometry(config);
    const NeuralSdf map = empty_map();  // not used while ICP registers

    Scan first = room_scan(Eigen::Isometry3d::Identity());
    EXPECT_EQ(odometry.estimate(first, map).source, PoseSource::kFirst);
    EXPECT_TRUE(odometry.poses().back().isApprox(Eigen::Isometry3d::Identity()));
    odometry.remember_scan(first);

    Vector6d xi;
    xi << 0.4, -0.1, 0.02, 0.0, 0.0, 0.035;  // 0.41 m, 2 deg of yaw
    const Eigen::Isometry3d truth = se3_exp(xi);
    Scan second = room_scan(truth);
    second.T_world_sensor.translation() = Eigen::Vector3d(7, 7, 7);  // ignored after scan 0
    const OdometryRecord& record = odometry.estimate(second, map);
    EXPECT_EQ(record.source, PoseSource::kIcp);
    EXPECT_EQ(record.tried, RegistrationMethod::kIcp);
    EXPECT_TRUE(record.accepted);
    EXPECT_LT(record.final_cost, record.initial_cost);
    EXPECT_GT(record.points, 500u);
    const Eigen::Isometry3d error = truth.inverse() * odometry.poses().back();
    EXPECT_LT(error.translation().norm(), kTranslationTolM);
    EXPECT_LT(rotation_angle_rad(error), kRotationTolRad);
    // The prediction was the identity (one pose behind): the registration moved it by the motion.
    EXPECT_NEAR(record.correction_m, truth.translation().norm(), 0.05);
}

TEST(ScanOdometry, FirstSweepIsBootstrappedFromTheSecondScanAndTheSecondRegistersSwept) {
    // A sensor moving at constant velocity: 8 m/s and 11 deg/s of yaw, the pose at each sweep's
    // start, so each sweep's motion is the motion between consecutive poses. Measured: the first
    // sweep 0.9 mm and 0.009 deg off, the second pose 1.2 mm and 0.006 deg off.
    Vector6d xi;
    xi << 0.8, 0.05, 0.0, 0.002, -0.001, 0.02;
    const Eigen::Isometry3d T_second = se3_exp(xi);
    const Scan first = swept_room_scan(Eigen::Isometry3d::Identity(), xi);
    const Scan second = swept_room_scan(T_second, xi);
    const NeuralSdf map = empty_map();  // not used while ICP registers

    ScanOdometry odometry(OdometryConfig{});
    EXPECT_EQ(odometry.estimate(first, map).source, PoseSource::kFirst);
    EXPECT_FALSE(odometry.records()[0].sweep_estimated);
    ASSERT_TRUE(odometry.bootstrap_sweep(first, second, 0.1));
    ASSERT_TRUE(odometry.records()[0].sweep_estimated);
    const Eigen::Isometry3d sweep_error = se3_exp(xi).inverse() * odometry.sweep_motion(0);
    std::printf("first sweep: %.3g m %.3g deg off\n", sweep_error.translation().norm(),
                rotation_angle_rad(sweep_error) * 180 / M_PI);
    EXPECT_LT(sweep_error.translation().norm(), kTranslationTolM);
    EXPECT_LT(rotation_angle_rad(sweep_error), kRotationTolRad);

    // Mapped deskewed (as the mapper does), the first scan is ICP's reference; the second
    // registers as measured with the first sweep's motion as its prior.
    Scan reference = first;
    reference.points_sensor =
        deskew_scan(first.points_sensor, first.point_time_s, odometry.sweep_motion(0), 0.1);
    odometry.remember_scan(reference);
    SweepPrior prior;
    prior.T_expected = odometry.sweep_motion(0);
    prior.interval_s = 0.1;
    const OdometryRecord& record = odometry.estimate(second, map, &prior);
    EXPECT_EQ(record.source, PoseSource::kIcp);
    EXPECT_TRUE(record.sweep_estimated);
    const Eigen::Isometry3d error = T_second.inverse() * odometry.poses().back();
    std::printf("second pose: %.3g m %.3g deg off\n", error.translation().norm(),
                rotation_angle_rad(error) * 180 / M_PI);
    EXPECT_LT(error.translation().norm(), kTranslationTolM);
    EXPECT_LT(rotation_angle_rad(error), kRotationTolRad);
}

TEST(ScanOdometry, FirstSweepIsNotBootstrappedWithoutPointTimes) {
    ScanOdometry odometry(OdometryConfig{});
    const NeuralSdf map = empty_map();
    const Scan first = room_scan(Eigen::Isometry3d::Identity());
    odometry.estimate(first, map);
    odometry.remember_scan(first);
    Vector6d xi;
    xi << 0.8, 0.0, 0.0, 0.0, 0.0, 0.02;
    EXPECT_FALSE(odometry.bootstrap_sweep(first, room_scan(se3_exp(xi)), 0.1));
    EXPECT_FALSE(odometry.records()[0].sweep_estimated);
    // The second scan's prediction stays the first pose (at rest).
    const OdometryRecord& record = odometry.estimate(room_scan(se3_exp(xi)), map);
    EXPECT_NEAR(record.correction_m, 0.8, 0.05);
}

TEST(ScanOdometry, MapRegistrationThatFailsKeepsIcpsPoseNotThePrediction) {
    // After the warm-up ICP finds the start of the registration to the map; where that one is not
    // accepted (here: a map without cells, so no point has an SDF value), ICP's pose stands.
    OdometryConfig config;
    config.icp_warmup_scans = 0;
    ASSERT_TRUE(config.icp_before_sdf);
    ScanOdometry odometry(config);
    const NeuralSdf map = empty_map();
    Scan first = room_scan(Eigen::Isometry3d::Identity());
    odometry.estimate(first, map);
    odometry.remember_scan(first);

    Vector6d xi;
    xi << 0.3, 0.2, 0.0, 0.0, 0.0, -0.03;
    const Eigen::Isometry3d truth = se3_exp(xi);
    const OdometryRecord& record = odometry.estimate(room_scan(truth), map);
    EXPECT_EQ(record.tried, RegistrationMethod::kSdf);
    EXPECT_FALSE(record.accepted);  // the last stage's verdict
    EXPECT_EQ(record.source, PoseSource::kIcp);
    EXPECT_GT(record.icp_inlier_ratio, 0.9);
    const Eigen::Isometry3d error = truth.inverse() * odometry.poses().back();
    EXPECT_LT(error.translation().norm(), kTranslationTolM);
    EXPECT_LT(rotation_angle_rad(error), kRotationTolRad);
}

TEST(ScanOdometry, ScanWithoutPointsIsSkippedAtThePrediction) {
    ScanOdometry odometry(OdometryConfig{});
    const NeuralSdf map = empty_map();
    Scan first = room_scan(Eigen::Isometry3d::Identity());
    odometry.estimate(first, map);
    odometry.remember_scan(first);

    Scan empty;
    empty.source = "empty";
    const OdometryRecord& record = odometry.estimate(empty, map);
    EXPECT_EQ(record.source, PoseSource::kSkipped);
    EXPECT_EQ(record.points, 0u);
    EXPECT_FALSE(odometry.mapped(1));
    EXPECT_TRUE(odometry.mapped(0));
    ASSERT_EQ(odometry.poses().size(), 2u);
    EXPECT_TRUE(odometry.poses()[1].isApprox(odometry.poses()[0]));  // at rest: one pose behind

    // An empty FIRST scan is skipped too (the world is still its identity pose).
    ScanOdometry fresh(OdometryConfig{});
    EXPECT_EQ(fresh.estimate(empty, map).source, PoseSource::kSkipped);
    EXPECT_TRUE(fresh.poses()[0].isApprox(Eigen::Isometry3d::Identity()));
}

TEST(ScanOdometry, PosesAndRecordsSurviveACheckpoint) {
    ScanOdometry odometry(OdometryConfig{});
    const NeuralSdf map = empty_map();
    Scan first = room_scan(Eigen::Isometry3d::Identity());
    odometry.estimate(first, map);
    odometry.remember_scan(first);
    Vector6d xi;
    xi << 0.3, 0.0, 0.0, 0.0, 0.0, 0.02;
    odometry.estimate(room_scan(se3_exp(xi)), map);

    const std::filesystem::path file =
        std::filesystem::temp_directory_path() / "shine_scan_odometry_checkpoint.bin";
    {
        std::ofstream stream(file, std::ios::binary);
        BinaryWriter out(stream);
        odometry.save(out);
    }
    ScanOdometry restored(OdometryConfig{});
    {
        BinaryReader in(file, "checkpoint");
        restored.load(in);
        in.expect_end();
    }
    std::filesystem::remove(file);
    ASSERT_EQ(restored.poses().size(), 2u);
    EXPECT_EQ(restored.poses()[1].matrix(), odometry.poses()[1].matrix());  // bit for bit
    EXPECT_EQ(restored.records()[1].source, odometry.records()[1].source);
    EXPECT_EQ(restored.records()[1].final_cost, odometry.records()[1].final_cost);
}

TEST(ScanOdometry, ConfigurationIsParsedAndChecked) {
    MapperConfig config;
    parse_config_yaml("odometry: {estimate_poses: true, voxel_size_m: 0.4, icp_warmup_scans: 5}",
                      "test", config);
    EXPECT_TRUE(config.odometry.estimate_poses);
    EXPECT_EQ(config.odometry.voxel_size_m, 0.4);
    EXPECT_EQ(config.odometry.icp_warmup_scans, 5);
    MapperConfig round_trip;
    parse_config_yaml(config_to_yaml(config), "round trip", round_trip);
    EXPECT_EQ(round_trip.odometry.icp_warmup_scans, 5);
    EXPECT_THROW(parse_config_yaml("odometry: {max_iterations: 0}", "test", config), ConfigError);
    EXPECT_THROW(parse_config_yaml("odometry: {kernel: 1}", "test", config), ConfigError);
    OdometryConfig bad;
    bad.max_range_m = bad.min_range_m;
    try {
        ScanOdometry odometry(bad);
        FAIL() << "an empty range window was accepted";
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("odometry.max_range_m"), std::string::npos);
    }
}

TEST(ScanOdometry, YawHypothesesFindATurnTheLocalRegistrationMisses) {
    // A keyframe turned by 100 degrees and moved 1.2 m: ICP from the prediction (at rest) stops
    // in a wrong minimum; from the headings 30 degrees apart one start lies in the right basin.
    Vector6d xi;
    xi << 1.0, 0.6, 0.0, 0.0, 0.0, 100.0 * M_PI / 180.0;
    const Eigen::Isometry3d truth = se3_exp(xi);
    const NeuralSdf map = empty_map();
    const auto run = [&](int hypotheses) {
        OdometryConfig config;
        config.icp_yaw_hypotheses = hypotheses;
        ScanOdometry odometry(config);
        const Scan first = room_scan(Eigen::Isometry3d::Identity());
        odometry.estimate(first, map);
        odometry.remember_scan(first);
        const OdometryRecord record = odometry.estimate(room_scan(truth), map);
        const Vector6d error = se3_log(truth.inverse() * odometry.poses().back());
        return std::make_tuple(record, error.head<3>().norm(), error.tail<3>().norm());
    };
    const auto [local, local_m, local_rad] = run(1);
    EXPECT_EQ(local.yaw_hypotheses, 0);
    // Short of the fitness that sends ICP to the headings (0.47 measured with the default
    // registration voxels of 0.5 m, 0.56 with 0.75 m).
    EXPECT_LT(local.icp_inlier_ratio, OdometryConfig{}.icp_min_inlier_ratio);
    EXPECT_GT(local_rad, 0.1) << "the local registration found the turn by itself";

    const auto [found, found_m, found_rad] = run(12);
    std::printf(
        "from the prediction: inliers %.3f, error %.3f m %.2f deg; 12 headings: %.3f, "
        "%.5f m %.4f deg\n",
        local.icp_inlier_ratio, local_m, local_rad * 180 / M_PI, found.icp_inlier_ratio, found_m,
        found_rad * 180 / M_PI);
    EXPECT_EQ(found.yaw_hypotheses, 12);
    EXPECT_TRUE(found.accepted);
    EXPECT_GT(found.icp_inlier_ratio, 0.9);
    EXPECT_LT(found_m, kTranslationTolM);
    EXPECT_LT(found_rad, kRotationTolRad);
}

TEST(ScanOdometry, PreparedAheadAndFinishedIsEstimateBitForBit) {
    // The mapper prepares scan k + 1 while the map trains on scan k, then finishes it: the same
    // poses and records as estimate(), and a prepared scan that another pose overtook is refused.
    OdometryConfig config;
    config.icp_warmup_scans = 0;  // ICP, then the registration to the map (here without cells)
    const NeuralSdf map = empty_map();
    Vector6d xi;
    xi << 0.3, 0.2, 0.0, 0.0, 0.0, -0.03;
    const Scan first = room_scan(Eigen::Isometry3d::Identity());
    const Scan second = room_scan(se3_exp(xi));
    const Scan third = room_scan(se3_exp(2.0 * xi));

    ScanOdometry whole(config), parts(config);
    for (const Scan* scan : {&first, &second, &third}) {
        whole.estimate(*scan, map);
        whole.remember_scan(*scan);
        PreparedScan prepared = parts.prepare(*scan);
        parts.finish(std::move(prepared), map);
        parts.remember_scan(*scan);
    }
    ASSERT_EQ(parts.poses().size(), 3u);
    for (std::size_t i = 0; i < 3; ++i) {
        EXPECT_TRUE(parts.poses()[i].matrix() == whole.poses()[i].matrix()) << "scan " << i;
        EXPECT_EQ(parts.records()[i].source, whole.records()[i].source) << "scan " << i;
        EXPECT_EQ(parts.records()[i].iterations, whole.records()[i].iterations) << "scan " << i;
        EXPECT_EQ(parts.records()[i].icp_inlier_ratio, whole.records()[i].icp_inlier_ratio);
    }
    EXPECT_EQ(parts.records()[2].source, PoseSource::kIcp);

    // Prepared as the fourth scan, but a fourth pose was kept first: refused, nothing kept.
    const PreparedScan stale = parts.prepare(third);
    parts.estimate(third, map);
    EXPECT_THROW(parts.finish(stale, map), std::logic_error);
    EXPECT_EQ(parts.poses().size(), 4u);
}
