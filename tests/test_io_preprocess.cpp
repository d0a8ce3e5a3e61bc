#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <tuple>

#include "shine/core/error.hpp"
#include "shine/core/per_point_values.hpp"
#include "shine/io/preprocess.hpp"

namespace {

shine::PreprocessConfig no_filters() {
    shine::PreprocessConfig c;
    c.min_range_m = 0.0;
    c.max_range_m = std::numeric_limits<double>::infinity();
    c.voxel_downsample_m = 0.0;
    return c;
}

const float kNaN = std::numeric_limits<float>::quiet_NaN();
const float kInf = std::numeric_limits<float>::infinity();

std::size_t dropped_total(const shine::PreprocessStats& s) {
    return s.dropped_nonfinite + s.dropped_zero_range + s.dropped_range + s.dropped_box +
           s.dropped_downsample;
}

}  // namespace

TEST(Preprocess, NonFinitePointsThrowUnderErrorPolicy) {
    const std::vector<Eigen::Vector3f> points = {{5, 0, 0}, {6, 0, 0}, {kNaN, 1, 1}, {0, kInf, 0}};
    shine::PreprocessConfig config = no_filters();
    config.invalid_points = shine::InvalidPointPolicy::kError;
    try {
        shine::preprocess_scan(points, config, "drive/000042.bin");
        FAIL() << "expected DataError";
    } catch (const shine::DataError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("000042.bin"), std::string::npos) << msg;
        EXPECT_NE(msg.find("point 2"), std::string::npos) << msg;
        EXPECT_NE(msg.find("invalid_points: drop"), std::string::npos) << msg;  // names the fix
    }
}

TEST(Preprocess, NonFinitePointsAreDroppedByDefault) {
    EXPECT_EQ(shine::PreprocessConfig{}.invalid_points, shine::InvalidPointPolicy::kDrop);
    const std::vector<Eigen::Vector3f> points = {{kNaN, 0, 0}, {5, 0, 0}, {0, kInf, 0}};
    shine::PreprocessStats stats;
    const auto out = shine::preprocess_scan(points, shine::PreprocessConfig{}, "s", &stats);
    ASSERT_EQ(out.size(), 1u);
    EXPECT_EQ(out[0], Eigen::Vector3f(5, 0, 0));
    EXPECT_EQ(stats.dropped_nonfinite, 2u);
}

TEST(Preprocess, ScansWithNoValidPointGiveAnEmptyResult) {
    shine::PreprocessStats stats;
    // Nothing at all (an empty KITTI .bin).
    EXPECT_TRUE(shine::preprocess_scan({}, shine::PreprocessConfig{}, "s", &stats).empty());
    EXPECT_EQ(stats.input, 0u);
    EXPECT_EQ(stats.output, 0u);
    // Only invalid and zero-range points, with downsampling on (the default).
    const std::vector<Eigen::Vector3f> points = {
        {kNaN, kNaN, kNaN}, {0, 0, 0}, {kInf, -kInf, 0}, {0, 0, 0}, {1, kNaN, 1}};
    const auto out = shine::preprocess_scan(points, shine::PreprocessConfig{}, "s", &stats);
    EXPECT_TRUE(out.empty());
    EXPECT_EQ(stats.input, 5u);
    EXPECT_EQ(stats.dropped_nonfinite, 3u);
    EXPECT_EQ(stats.dropped_zero_range, 2u);
    EXPECT_EQ(stats.output, 0u);
}

TEST(Preprocess, NonFinitePointsAreCountedUnderDropPolicy) {
    const std::vector<Eigen::Vector3f> points = {{5, 0, 0},     {kNaN, 1, 1}, {6, 0, 0},
                                                 {0, -kInf, 0}, {0, 0, kNaN}, {7, 0, 0}};
    shine::PreprocessConfig config = no_filters();
    config.invalid_points = shine::InvalidPointPolicy::kDrop;
    shine::PreprocessStats stats;
    const auto out = shine::preprocess_scan(points, config, "scan.ply", &stats);
    const std::vector<Eigen::Vector3f> expected = {{5, 0, 0}, {6, 0, 0}, {7, 0, 0}};
    EXPECT_EQ(out, expected);  // order kept without downsampling
    EXPECT_EQ(stats.input, 6u);
    EXPECT_EQ(stats.dropped_nonfinite, 3u);
    EXPECT_EQ(stats.output, 3u);
}

TEST(Preprocess, ZeroRangeAndRangeCrop) {
    const std::vector<Eigen::Vector3f> points = {{0, 0, 0},   {1, 0, 0}, {0, 2, 0},     {0, 0, 10},
                                                 {30, 40, 0}, {0, 0, 0}, {-60.5f, 0, 0}};
    shine::PreprocessConfig config = no_filters();
    // Zero-range points go even when min_range_m is 0: they are "no return", not geometry.
    shine::PreprocessStats stats;
    auto out = shine::preprocess_scan(points, config, "s", &stats);
    EXPECT_EQ(out.size(), 5u);
    EXPECT_EQ(stats.dropped_zero_range, 2u);

    config.min_range_m = 1.5;
    config.max_range_m = 50.0;
    out = shine::preprocess_scan(points, config, "s", &stats);
    const std::vector<Eigen::Vector3f> expected = {{0, 2, 0}, {0, 0, 10}, {30, 40, 0}};
    EXPECT_EQ(out, expected);  // 50 m exactly is kept: the bound is inclusive
    EXPECT_EQ(stats.dropped_zero_range, 2u);
    EXPECT_EQ(stats.dropped_range, 2u);
    EXPECT_EQ(stats.input, stats.output + dropped_total(stats));
}

TEST(Preprocess, BoxCrop) {
    const std::vector<Eigen::Vector3f> points = {
        {5, 5, 0}, {5, -5, 0}, {-20, 0, 0}, {5, 0, 3}, {5, 0, -2.5f}};
    shine::PreprocessConfig config = no_filters();
    config.box_min_sensor_m = Eigen::Vector3d(-10, -10, -2);
    config.box_max_sensor_m = Eigen::Vector3d(10, 10, 2);
    shine::PreprocessStats stats;
    const auto out = shine::preprocess_scan(points, config, "s", &stats);
    const std::vector<Eigen::Vector3f> expected = {{5, 5, 0}, {5, -5, 0}};
    EXPECT_EQ(out, expected);
    EXPECT_EQ(stats.dropped_box, 3u);
}

TEST(Preprocess, DownsampleKeepsThePointNearestTheVoxelCentre) {
    shine::PreprocessConfig config = no_filters();
    config.voxel_downsample_m = 1.0;
    // Voxel [2,3)x[0,1)x[0,1) has centre (2.5, 0.5, 0.5).
    const std::vector<Eigen::Vector3f> points = {{2.1f, 0.1f, 0.1f},
                                                 {2.45f, 0.55f, 0.5f},  // nearest
                                                 {2.9f, 0.9f, 0.9f},
                                                 {2.5f, 0.2f, 0.5f},
                                                 // Another voxel, alone.
                                                 {-0.5f, 0.5f, 0.5f}};
    shine::PreprocessStats stats;
    const auto out = shine::preprocess_scan(points, config, "s", &stats);
    ASSERT_EQ(out.size(), 2u);
    // Sorted by voxel key: x key -1 before x key 2.
    EXPECT_EQ(out[0], Eigen::Vector3f(-0.5f, 0.5f, 0.5f));
    EXPECT_EQ(out[1], Eigen::Vector3f(2.45f, 0.55f, 0.5f));
    EXPECT_EQ(stats.dropped_downsample, 3u);
    EXPECT_EQ(stats.output, 2u);
}

TEST(Preprocess, DownsampleIsIndependentOfPointOrder) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(-20.0f, 20.0f);
    std::vector<Eigen::Vector3f> points;
    for (int i = 0; i < 20000; ++i) points.emplace_back(u(rng), u(rng), u(rng) * 0.1f);
    // Exact duplicates and points equidistant from a centre exercise the tie-break.
    for (int i = 0; i < 200; ++i) points.push_back(points[i]);
    points.emplace_back(0.25f, 0.25f, 0.25f);
    points.emplace_back(0.25f, 0.25f, 0.75f);  // same voxel, same distance to its centre
    shine::PreprocessConfig config = no_filters();
    config.voxel_downsample_m = 1.0;
    const auto reference = shine::preprocess_scan(points, config, "s");
    EXPECT_LT(reference.size(), points.size());
    EXPECT_GT(reference.size(), 1000u);

    for (unsigned seed : {1u, 2u, 3u}) {
        std::vector<Eigen::Vector3f> shuffled = points;
        std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(seed));
        const auto out = shine::preprocess_scan(shuffled, config, "s");
        ASSERT_EQ(out.size(), reference.size());
        EXPECT_TRUE(out == reference) << "seed " << seed;
    }

    // Exactly one output point per occupied voxel.
    std::set<std::tuple<long, long, long>> occupied, kept;
    for (const auto& p : points) {
        occupied.emplace(std::lround(std::floor(p.x())), std::lround(std::floor(p.y())),
                         std::lround(std::floor(p.z())));
    }
    for (const auto& p : reference) {
        kept.emplace(std::lround(std::floor(p.x())), std::lround(std::floor(p.y())),
                     std::lround(std::floor(p.z())));
    }
    EXPECT_EQ(kept.size(), reference.size());
    EXPECT_EQ(kept, occupied);
}

TEST(Preprocess, StatsAccumulate) {
    shine::PreprocessStats a, b;
    a.input = 10;
    a.dropped_range = 2;
    a.output = 8;
    b.input = 5;
    b.dropped_box = 1;
    b.dropped_downsample = 3;
    b.output = 1;
    a += b;
    EXPECT_EQ(a.input, 15u);
    EXPECT_EQ(a.dropped_range, 2u);
    EXPECT_EQ(a.dropped_box, 1u);
    EXPECT_EQ(a.dropped_downsample, 3u);
    EXPECT_EQ(a.output, 9u);
}

TEST(Preprocess, InvalidConfigurationNamesTheKey) {
    const std::vector<Eigen::Vector3f> points = {{5, 0, 0}};
    shine::PreprocessConfig config;
    config.voxel_downsample_m = -0.1;
    try {
        shine::preprocess_scan(points, config, "s");
        FAIL() << "expected ConfigError";
    } catch (const shine::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("voxel_downsample_m"), std::string::npos);
    }
    config = shine::PreprocessConfig{};
    config.max_range_m = 1.0;  // below the default min_range_m of 1.5
    EXPECT_THROW(shine::preprocess_scan(points, config, "s"), shine::ConfigError);
    config = shine::PreprocessConfig{};
    config.box_min_sensor_m.x() = 5;
    config.box_max_sensor_m.x() = -5;
    EXPECT_THROW(shine::preprocess_scan(points, config, "s"), shine::ConfigError);
}

TEST(Preprocess, DownsampleBreaksDistanceTiesIndependentlyOfOrder) {
    shine::PreprocessConfig config = no_filters();
    config.voxel_downsample_m = 1.0;
    // Both points lie 0.25 voxels from the centre (0.5, 0.5, 0.5) of the same voxel.
    const Eigen::Vector3f a(0.25f, 0.5f, 0.5f), b(0.75f, 0.5f, 0.5f);
    const auto ab = shine::preprocess_scan({a, b}, config, "s");
    const auto ba = shine::preprocess_scan({b, a}, config, "s");
    ASSERT_EQ(ab.size(), 1u);
    EXPECT_EQ(ab, ba);
    EXPECT_EQ(ab[0], a);  // the lexicographically smaller point wins the tie
}

TEST(Preprocess, SourceIndexNamesTheInputPointOfEachOutputPoint) {
    using namespace shine;
    // Random points (some out of range, one NaN) through each path: no thinning, thinning, and
    // every point grouped by voxel. Each output point is the input point its index names, and
    // asking for the indices changes nothing else.
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-30.0f, 30.0f);
    std::vector<Eigen::Vector3f> points;
    for (int i = 0; i < 40000; ++i) points.emplace_back(u(rng), u(rng), 0.1f * u(rng));
    points[17] = Eigen::Vector3f(NAN, 0.0f, 0.0f);
    for (const double voxel_m : {0.0, 0.5}) {
        for (const VoxelPoints mode : {VoxelPoints::kNearest, VoxelPoints::kAll}) {
            PreprocessConfig config;
            config.voxel_downsample_m = voxel_m;
            config.voxel_points = mode;
            config.max_range_m = 35.0;
            std::vector<std::uint32_t> groups, groups_plain, index;
            const auto plain = preprocess_scan(points, config, "random", nullptr, &groups_plain);
            const auto out = preprocess_scan(points, config, "random", nullptr, &groups, &index);
            ASSERT_EQ(out, plain);
            EXPECT_EQ(groups, groups_plain);
            ASSERT_EQ(index.size(), out.size());
            ASSERT_LT(out.size(), points.size());
            for (std::size_t k = 0; k < out.size(); ++k) {
                ASSERT_LT(index[k], points.size());
                ASSERT_EQ(out[k], points[index[k]]) << k;
            }
        }
    }
}

TEST(Preprocess, PerPointValuesFollowTheirPointsThroughEveryFilter) {
    using namespace shine;
    // Hand-picked points, each with its own intensity, through the NaN, range and voxel filters
    // (1 m voxels): the kept ones come out sorted by voxel with their own intensities.
    const std::vector<Eigen::Vector3f> points = {
        {0.5f, 0.0f, 0.0f},    // 10: closer than min_range_m
        {5.5f, 0.5f, 0.5f},    // 20: the centre of voxel (5, 0, 0), kept
        {NAN, 1.0f, 1.0f},     // 30: not finite
        {5.9f, 0.9f, 0.9f},    // 40: same voxel as 20, farther from its centre: thinned away
        {-7.5f, 2.5f, 0.5f},   // NaN intensity: kept, its intensity unknown
        {70.0f, 0.0f, 0.0f},   // 50: beyond max_range_m
        {0.0f, 12.5f, 3.5f}};  // 0: kept, a zero intensity is a value
    const std::vector<float> intensity = {10.0f, 20.0f, 30.0f, 40.0f, NAN, 50.0f, 0.0f};
    PreprocessConfig config;
    config.voxel_downsample_m = 1.0;
    std::vector<std::uint32_t> index;
    const auto kept = preprocess_scan(points, config, "hand", nullptr, nullptr, &index);
    const std::vector<float> kept_intensity = gather_per_point(intensity, points.size(), index);
    ASSERT_EQ(kept.size(), 3u);
    ASSERT_EQ(kept_intensity.size(), 3u);
    // Voxel keys (-8, 2, 0) < (0, 12, 3) < (5, 0, 0).
    EXPECT_EQ(kept[0], points[4]);
    EXPECT_TRUE(std::isnan(kept_intensity[0]));
    EXPECT_EQ(kept[1], points[6]);
    EXPECT_EQ(kept_intensity[1], 0.0f);
    EXPECT_EQ(kept[2], points[1]);
    EXPECT_EQ(kept_intensity[2], 20.0f);
    // A quantity the scan does not have stays empty.
    EXPECT_TRUE(gather_per_point(std::vector<float>{}, points.size(), index).empty());
    // Dropping by flag keeps every array of the points' size in step, and leaves the others.
    std::vector<Eigen::Vector3f> p = points;
    std::vector<float> v = intensity;
    std::vector<double> none;
    std::vector<std::uint8_t> flags(points.size(), 0);
    flags[0] = flags[2] = flags[5] = 1;
    EXPECT_EQ(drop_flagged(flags, p, v, none), 3u);
    ASSERT_EQ(p.size(), 4u);
    ASSERT_EQ(v.size(), 4u);
    EXPECT_EQ(p[2], points[4]);
    EXPECT_TRUE(std::isnan(v[2]));
    EXPECT_EQ(v[3], 0.0f);
    EXPECT_EQ(v[1], 40.0f);
    EXPECT_TRUE(none.empty());
}
