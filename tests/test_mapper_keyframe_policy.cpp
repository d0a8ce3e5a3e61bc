// The keyframe policy (keyframe_policy.hpp): which registered scans train the map when they come,
// which are deferred, and how a budget's account defers keyframes and lets them through again.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "shine/core/error.hpp"
#include "shine/io/binary_stream.hpp"
#include "shine/mapper/keyframe_policy.hpp"
#include "shine/mapper/scan_odometry.hpp"

using namespace shine;

namespace {

/// A scan registered to the map's SDF with `coverage` of its 1000 points inside the map.
OdometryRecord sdf_record(double coverage) {
    OdometryRecord r;
    r.source = PoseSource::kSdf;
    r.tried = RegistrationMethod::kSdf;
    r.accepted = true;
    r.points = 1000;
    r.valid_points = static_cast<std::uint64_t>(coverage * 1000.0);
    return r;
}

Eigen::Isometry3d at_x(double x_m) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation().x() = x_m;
    return T;
}

OdometryRecord first_record() {
    OdometryRecord r;
    r.source = PoseSource::kFirst;
    return r;
}

}  // namespace

TEST(KeyframePolicy, TrainsNewGroundAndDefersWhatTheMapAlreadyHas) {
    KeyframeConfig config;
    config.min_translation_m = 4.0;
    config.max_interval_scans = 4;
    config.min_coverage = 0.75;
    KeyframePolicy policy(config);
    KeyframeChoice c = policy.choose(first_record(), at_x(0.0));
    EXPECT_TRUE(c.train);
    EXPECT_EQ(c.reason, KeyframeReason::kFirst);
    policy.record(c, at_x(0.0), 0.2, 0.15);

    // ICP's warm-up (or a pose that is only the prediction) trains: the map is not its judge yet.
    OdometryRecord icp = sdf_record(0.99);
    icp.source = PoseSource::kIcp;
    c = policy.choose(icp, at_x(0.5));
    EXPECT_TRUE(c.train);
    EXPECT_EQ(c.reason, KeyframeReason::kWarmup);
    policy.record(c, at_x(0.5), 0.2, 0.15);

    // Covered and close: deferred, until the 4th scan after the keyframe.
    for (int k = 1; k <= 4; ++k) {
        c = policy.choose(sdf_record(0.9), at_x(0.5 + 0.5 * k));
        if (k < 4) {
            EXPECT_FALSE(c.train) << k;
            EXPECT_EQ(c.reason, KeyframeReason::kRedundant);
        } else {
            EXPECT_TRUE(c.train);
            EXPECT_EQ(c.reason, KeyframeReason::kInterval);
        }
        policy.record(c, at_x(0.5 + 0.5 * k), 0.03, c.train ? 0.15 : 0.0);
    }
    // The last keyframe is at x = 2.5: 4 m further is motion, less coverage is new ground.
    EXPECT_EQ(policy.choose(sdf_record(0.9), at_x(6.5)).reason, KeyframeReason::kMotion);
    EXPECT_EQ(policy.choose(sdf_record(0.7), at_x(2.6)).reason, KeyframeReason::kCoverage);
    EXPECT_FALSE(policy.choose(sdf_record(0.9), at_x(6.4)).train);
    Eigen::Isometry3d turned = at_x(2.5);
    turned.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    EXPECT_EQ(policy.choose(sdf_record(0.9), turned).reason, KeyframeReason::kMotion);

    EXPECT_EQ(policy.counts().trained, 3u);
    EXPECT_EQ(policy.counts().deferred, 3u);
}

TEST(KeyframePolicy, DisabledTrainsEveryScan) {
    KeyframeConfig config;
    config.enabled = false;
    KeyframePolicy policy(config);
    for (int k = 0; k < 5; ++k) {
        const KeyframeChoice c = policy.choose(sdf_record(1.0), at_x(0.01 * k));
        EXPECT_TRUE(c.train);
        EXPECT_EQ(c.reason, KeyframeReason::kDisabled);
        policy.record(c, at_x(0.01 * k), 0.1, 0.1);
    }
}

TEST(KeyframePolicy, BudgetDefersKeyframesUntilTheAccountPaysForTheirTraining) {
    KeyframeConfig config;
    config.max_interval_scans = 1;  // every scan is a keyframe, unless the budget says no
    config.max_ms_per_scan = 100.0;
    config.forced_coverage = 0.5;
    KeyframePolicy policy(config);
    KeyframeChoice c = policy.choose(first_record(), at_x(0.0));
    ASSERT_TRUE(c.train);
    policy.record(c, at_x(0.0), 0.3, 0.27);  // 200 ms over: the account owes 0.2 s
    EXPECT_NEAR(policy.saved_seconds(), -0.2, 1e-12);
    // Registration-only scans at 30 ms bring 70 ms each; training needs the 0.27 s the last
    // keyframe's training took: 0.47 s to make up, the 7th scan's turn.
    int deferred = 0;
    for (int k = 1; k <= 10; ++k) {
        c = policy.choose(sdf_record(0.9), at_x(0.1 * k));
        if (c.train) break;
        EXPECT_EQ(c.reason, KeyframeReason::kBudget);
        policy.record(c, at_x(0.1 * k), 0.03, 0.0);
        ++deferred;
    }
    EXPECT_TRUE(c.train);
    EXPECT_EQ(deferred, 7);
    EXPECT_EQ(policy.counts().over_budget, 7u);
    // A scan the map hardly covers trains whatever the account holds.
    policy.record(c, at_x(0.8), 0.6, 0.57);  // 0.29 s saved, 0.5 s over: 0.21 s owed
    EXPECT_NEAR(policy.saved_seconds(), -0.21, 1e-9);
    EXPECT_TRUE(policy.choose(sdf_record(0.4), at_x(0.9)).train);
    EXPECT_FALSE(policy.choose(sdf_record(0.6), at_x(0.9)).train);
}

TEST(KeyframePolicy, SavedTimeIsCapped) {
    KeyframeConfig config;
    config.max_ms_per_scan = 100.0;
    config.max_saved_scans = 3.0;
    KeyframePolicy policy(config);
    KeyframeChoice c = policy.choose(first_record(), at_x(0.0));
    policy.record(c, at_x(0.0), 0.05, 0.04);
    for (int k = 0; k < 20; ++k)
        policy.record({false, KeyframeReason::kRedundant}, at_x(0), 0.0, 0);
    EXPECT_NEAR(policy.saved_seconds(), 0.3, 1e-12);
}

TEST(KeyframePolicy, StateRoundTripsThroughACheckpoint) {
    KeyframeConfig config;
    config.max_ms_per_scan = 80.0;
    KeyframePolicy policy(config);
    policy.record(policy.choose(first_record(), at_x(0.0)), at_x(0.0), 0.2, 0.1);
    policy.record(policy.choose(sdf_record(0.95), at_x(1.0)), at_x(1.0), 0.03, 0.0);
    const std::filesystem::path path =
        std::filesystem::path(::testing::TempDir()) / "keyframe_policy_state.bin";
    {
        std::ofstream file(path, std::ios::binary | std::ios::trunc);
        BinaryWriter out(file);
        policy.save(out);
    }
    BinaryReader in(path, "checkpoint");
    KeyframePolicy loaded(config);
    loaded.load(in);
    in.expect_end();
    EXPECT_EQ(loaded.counts().trained, policy.counts().trained);
    EXPECT_EQ(loaded.counts().deferred, policy.counts().deferred);
    EXPECT_DOUBLE_EQ(loaded.saved_seconds(), policy.saved_seconds());
    const KeyframeChoice a = policy.choose(sdf_record(0.95), at_x(4.5));
    const KeyframeChoice b = loaded.choose(sdf_record(0.95), at_x(4.5));
    EXPECT_EQ(a.train, b.train);
    EXPECT_EQ(a.reason, b.reason);
}

TEST(KeyframePolicy, InvalidSettingsNameTheirKey) {
    KeyframeConfig config;
    config.max_interval_scans = 0;
    try {
        KeyframePolicy policy(config);
        FAIL() << "no error";
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("keyframes.max_interval_scans"), std::string::npos);
    }
    config = KeyframeConfig{};
    config.forced_coverage = 0.9;  // above min_coverage
    EXPECT_THROW(KeyframePolicy{config}, ConfigError);
}
