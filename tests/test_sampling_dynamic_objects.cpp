// Dynamic objects (dynamic_objects.hpp): the votes of part of a compact object spread to all of
// it, never to the ground under it, to a structure wider than a car, to an object too few of
// whose points are dynamic, or to a separate object next to it.
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/sampling/dynamic_objects.hpp"

using namespace shine;

namespace {

/// A scan of one flat ground (20 x 20 m at z = 0, 0.2 m apart) and boxes' surfaces (0.1 m
/// apart); `first_of` gives where each box's points start.
struct Scene {
    std::vector<Eigen::Vector3f> points;
    std::vector<std::size_t> first_of;
    std::size_t ground_points = 0;
};

void add_box(Scene& scene, const Eigen::Vector3f& lo, const Eigen::Vector3f& hi) {
    scene.first_of.push_back(scene.points.size());
    const float step = 0.1f;
    for (float x = lo.x(); x <= hi.x(); x += step) {
        for (float y = lo.y(); y <= hi.y(); y += step) {
            scene.points.emplace_back(x, y, hi.z());  // top
        }
        for (float z = lo.z(); z <= hi.z(); z += step) {
            scene.points.emplace_back(x, lo.y(), z);  // sides
            scene.points.emplace_back(x, hi.y(), z);
        }
    }
    for (float y = lo.y(); y <= hi.y(); y += step) {
        for (float z = lo.z(); z <= hi.z(); z += step) {
            scene.points.emplace_back(lo.x(), y, z);  // ends
            scene.points.emplace_back(hi.x(), y, z);
        }
    }
}

Scene ground() {
    Scene scene;
    for (float x = -10; x <= 10; x += 0.2f) {
        for (float y = -10; y <= 10; y += 0.2f) scene.points.emplace_back(x, y, 0.0f);
    }
    scene.ground_points = scene.points.size();
    return scene;
}

/// Flags every `every`-th point of [begin, end).
void flag(std::vector<std::uint8_t>& dynamic, std::size_t begin, std::size_t end, int every) {
    for (std::size_t i = begin; i < end; i += every) dynamic[i] = 1;
}

std::size_t count(const std::vector<std::uint8_t>& dynamic, std::size_t begin, std::size_t end) {
    std::size_t n = 0;
    for (std::size_t i = begin; i < end; ++i) n += dynamic[i];
    return n;
}

}  // namespace

TEST(DynamicObjects, ACarWithAFewDynamicPointsIsDynamicWholeAndTheGroundUnderItIsNot) {
    Scene scene = ground();
    add_box(scene, {-2.0f, 1.0f, 0.3f}, {2.4f, 2.8f, 1.5f});  // a car body above the road
    const std::size_t car = scene.first_of[0], end = scene.points.size();
    std::vector<std::uint8_t> dynamic(scene.points.size(), 0);
    flag(dynamic, car, end, 5);                  // 20 % of the car seen through
    flag(dynamic, 0, scene.ground_points, 500);  // a few ground points too
    const std::size_t ground_flags = count(dynamic, 0, scene.ground_points);
    const DynamicObjectStats stats = spread_dynamic_to_objects(scene.points, dynamic, {});
    EXPECT_EQ(count(dynamic, car, end), end - car);
    EXPECT_EQ(count(dynamic, 0, scene.ground_points), ground_flags);
    EXPECT_EQ(stats.objects, 1u);
    EXPECT_EQ(stats.objects_dynamic, 1u);
    EXPECT_EQ(stats.points_added, (end - car) - ((end - car + 4) / 5));
}

TEST(DynamicObjects, AWallWiderThanACarKeepsItsPointsOwnVotes) {
    Scene scene = ground();
    add_box(scene, {-9.0f, 5.0f, 0.0f}, {9.0f, 5.3f, 3.0f});  // an 18 m wall
    const std::size_t wall = scene.first_of[0], end = scene.points.size();
    std::vector<std::uint8_t> dynamic(scene.points.size(), 0);
    flag(dynamic, wall, end, 3);  // a third seen through (grazing angles)
    const std::vector<std::uint8_t> before = dynamic;
    const DynamicObjectStats stats = spread_dynamic_to_objects(scene.points, dynamic, {});
    EXPECT_EQ(dynamic, before);
    EXPECT_EQ(stats.objects_dynamic, 0u);
}

TEST(DynamicObjects, TooFewDynamicPointsOrAShareBelowTheThresholdSpreadNothing) {
    Scene scene = ground();
    add_box(scene, {-2.0f, 1.0f, 0.3f}, {2.4f, 2.8f, 1.5f});
    const std::size_t car = scene.first_of[0], end = scene.points.size();
    std::vector<std::uint8_t> dynamic(scene.points.size(), 0);
    flag(dynamic, car, end, 10);  // 10 %: below the 15 % share
    std::vector<std::uint8_t> before = dynamic;
    spread_dynamic_to_objects(scene.points, dynamic, {});
    EXPECT_EQ(dynamic, before);

    // A pedestrian of 12 points with 2 of them dynamic: a share of 17 %, but fewer than 3.
    Scene small = ground();
    const std::size_t person = small.points.size();
    for (int k = 0; k < 12; ++k) small.points.emplace_back(3.0f, 3.0f, 0.3f + 0.12f * k);
    std::vector<std::uint8_t> flags(small.points.size(), 0);
    flags[person] = flags[person + 5] = 1;
    before = flags;
    spread_dynamic_to_objects(small.points, flags, {});
    EXPECT_EQ(flags, before);
    flags[person + 9] = 1;  // a third one: now it spreads
    spread_dynamic_to_objects(small.points, flags, {});
    EXPECT_EQ(count(flags, person, small.points.size()), 12u);
}

TEST(DynamicObjects, SeparateObjectsDoNotShareTheirVotesAndZeroShareIsOff) {
    Scene scene = ground();
    add_box(scene, {-6.0f, 1.0f, 0.3f}, {-2.0f, 2.8f, 1.5f});
    add_box(scene, {-1.0f, 1.0f, 0.3f}, {3.0f, 2.8f, 1.5f});  // 1 m apart
    const std::size_t a = scene.first_of[0], b = scene.first_of[1], end = scene.points.size();
    std::vector<std::uint8_t> dynamic(scene.points.size(), 0);
    flag(dynamic, a, b, 4);
    std::vector<std::uint8_t> off = dynamic;
    DynamicObjectConfig config;
    config.min_dynamic_share = 0.0f;
    const std::vector<std::uint8_t> before = off;
    spread_dynamic_to_objects(scene.points, off, config);
    EXPECT_EQ(off, before);

    spread_dynamic_to_objects(scene.points, dynamic, {});
    EXPECT_EQ(count(dynamic, a, b), b - a);
    EXPECT_EQ(count(dynamic, b, end), 0u);
}

TEST(DynamicObjects, MismatchedFlagsAndBadSettingsAreErrors) {
    const std::vector<Eigen::Vector3f> points = {{0, 0, 0}, {1, 0, 0}};
    std::vector<std::uint8_t> flags(1, 0);
    EXPECT_THROW(spread_dynamic_to_objects(points, flags, {}), DataError);
    flags.assign(2, 0);
    DynamicObjectConfig config;
    config.voxel_m = 0.0f;
    EXPECT_THROW(spread_dynamic_to_objects(points, flags, config), ConfigError);
    config = {};
    config.min_dynamic_share = 1.5f;
    EXPECT_THROW(spread_dynamic_to_objects(points, flags, config), ConfigError);
}
