// Moving objects (moving_objects.hpp): a car driving through the scans and the few returns of a
// far car are moving in every scan; parked cars, a wall, a walking pedestrian, the ground and
// static objects sampled anew in every scan are not, also across the chunks long sequences are
// processed in.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/sampling/moving_objects.hpp"

using namespace shine;

namespace {

/// Where each thing's points lie in a scan's point list.
struct Part {
    std::size_t begin = 0, end = 0;
};

/// Surface points of an axis-aligned box, `spacing` apart, each moved by up to `jitter` (a
/// scan's own sampling of the same surface).
Part add_box(std::vector<Eigen::Vector3f>& points, const Eigen::Vector3f& lo,
             const Eigen::Vector3f& hi, float spacing, float jitter, std::mt19937& rng) {
    std::uniform_real_distribution<float> noise(-jitter, jitter);
    const auto add = [&](float x, float y, float z) {
        points.emplace_back(x + noise(rng), y + noise(rng), z + noise(rng));
    };
    Part part{points.size(), 0};
    for (float x = lo.x(); x <= hi.x() + 1e-4f; x += spacing) {
        for (float y = lo.y(); y <= hi.y() + 1e-4f; y += spacing) add(x, y, hi.z());
        for (float z = lo.z(); z <= hi.z() + 1e-4f; z += spacing) {
            add(x, lo.y(), z);
            add(x, hi.y(), z);
        }
    }
    for (float y = lo.y(); y <= hi.y() + 1e-4f; y += spacing) {
        for (float z = lo.z(); z <= hi.z() + 1e-4f; z += spacing) {
            add(lo.x(), y, z);
            add(hi.x(), y, z);
        }
    }
    part.end = points.size();
    return part;
}

/// A street scan: ground, two parked cars and a wall (static, sampled with jitter), a car
/// driving at car_step_m a scan (1.3 m: 13 m/s at 10 Hz), a pedestrian walking at 0.15 m a scan,
/// and a far car's front: one column of four returns 0.42 m apart (a 64-beam sensor at 57 m)
/// closing at 1.37 m a scan.
struct StreetScan {
    std::vector<Eigen::Vector3f> points;
    Part ground, parked_a, parked_b, wall, car, pedestrian, far_car;
};

StreetScan street_scan(int scan, float jitter, float car_step_m = 1.3f) {
    std::mt19937 rng(static_cast<unsigned>(1000 + scan));
    StreetScan s;
    s.ground.begin = 0;
    for (float x = -40.0f; x <= 40.0f; x += 0.25f) {
        for (float y = -8.0f; y <= 8.0f; y += 0.25f) s.points.emplace_back(x, y, 0.0f);
    }
    s.ground.end = s.points.size();
    s.parked_a = add_box(s.points, {0.0f, 4.0f, 0.0f}, {4.5f, 5.8f, 1.5f}, 0.15f, jitter, rng);
    s.parked_b = add_box(s.points, {6.0f, 4.0f, 0.0f}, {10.5f, 5.8f, 1.5f}, 0.15f, jitter, rng);
    s.wall = add_box(s.points, {-12.0f, 6.5f, 0.0f}, {-6.0f, 6.7f, 2.5f}, 0.15f, jitter, rng);
    const float car_x = -12.0f + car_step_m * static_cast<float>(scan);
    s.car = add_box(s.points, {car_x, -3.2f, 0.0f}, {car_x + 4.5f, -1.4f, 1.5f}, 0.15f, 0.0f, rng);
    const float walker_x = -4.0f + 0.15f * static_cast<float>(scan);
    s.pedestrian =
        add_box(s.points, {walker_x, -7.0f, 0.0f}, {walker_x + 0.5f, -6.5f, 1.8f}, 0.1f, 0.0f, rng);
    s.far_car.begin = s.points.size();
    const float far_x = -38.0f + 1.37f * static_cast<float>(scan);
    for (float z : {0.25f, 0.67f, 1.09f, 1.51f}) s.points.emplace_back(far_x, 2.3f, z);
    s.far_car.end = s.points.size();
    return s;
}

std::size_t count(const std::vector<std::uint8_t>& flags, const Part& part) {
    std::size_t n = 0;
    for (std::size_t i = part.begin; i < part.end; ++i) n += flags[i];
    return n;
}

/// A part's points at least min_height_m (0.2 m) above the ground: those of an object (lower
/// ones are ground, dynamic_objects.hpp).
std::size_t above_ground(const StreetScan& scan, const Part& part) {
    std::size_t n = 0;
    for (std::size_t i = part.begin; i < part.end; ++i) n += scan.points[i].z() >= 0.2f;
    return n;
}

std::vector<std::vector<std::uint8_t>> moving_of(const std::vector<StreetScan>& scans,
                                                 const MovingObjectConfig& config,
                                                 MovingObjectStats* stats = nullptr) {
    std::vector<const std::vector<Eigen::Vector3f>*> points;
    for (const StreetScan& s : scans) points.push_back(&s.points);
    return find_moving_points(points, DynamicObjectConfig{}, config, stats);
}

}  // namespace

TEST(MovingObjects, DrivingCarsMoveInEveryScanAndNothingStaticDoes) {
    std::vector<StreetScan> scans;
    for (int s = 0; s < 12; ++s) scans.push_back(street_scan(s, 0.03f));
    MovingObjectStats stats;
    const auto moving = moving_of(scans, MovingObjectConfig{}, &stats);
    ASSERT_EQ(moving.size(), scans.size());
    for (std::size_t s = 0; s < scans.size(); ++s) {
        const StreetScan& scan = scans[s];
        ASSERT_EQ(moving[s].size(), scan.points.size());
        SCOPED_TRACE("scan " + std::to_string(s));
        EXPECT_EQ(count(moving[s], scan.car), above_ground(scan, scan.car));
        EXPECT_EQ(count(moving[s], scan.far_car), 4u);
        EXPECT_EQ(count(moving[s], scan.ground), 0u);
        EXPECT_EQ(count(moving[s], scan.parked_a), 0u);
        EXPECT_EQ(count(moving[s], scan.parked_b), 0u);
        EXPECT_EQ(count(moving[s], scan.wall), 0u);
        // 0.15 m a scan is slower than min_step_m: people walking stay to their own votes.
        EXPECT_EQ(count(moving[s], scan.pedestrian), 0u);
    }
    EXPECT_EQ(stats.moving_objects, 2 * scans.size());
    EXPECT_GE(stats.moved, stats.moving_objects / 2);
}

TEST(MovingObjects, AFarCarsFewReturnsAreOneObjectOnlyInTallVoxels) {
    // With the segmentation's cubic voxels of 0.3 m the far car's rows (0.42 m apart) are four
    // single points, too few for an object: no velocity, not moving.
    std::vector<StreetScan> scans;
    for (int s = 0; s < 12; ++s) scans.push_back(street_scan(s, 0.03f));
    MovingObjectConfig cubic;
    cubic.voxel_height_m = 0.0f;
    const auto moving = moving_of(scans, cubic);
    for (std::size_t s = 0; s < scans.size(); ++s) {
        EXPECT_EQ(count(moving[s], scans[s].far_car), 0u);
        EXPECT_EQ(count(moving[s], scans[s].car), above_ground(scans[s], scans[s].car));
    }
}

TEST(MovingObjects, AStaticStreetHasNoMovingObject) {
    // Static objects sampled anew in every scan (jitter of 5 cm) and a few scans only.
    for (std::size_t length : {2u, 3u, 12u}) {
        std::vector<StreetScan> scans;
        for (std::size_t s = 0; s < length; ++s) {
            StreetScan scan = street_scan(static_cast<int>(s), 0.05f);
            // The movers stand still: the first scan's car, pedestrian and far car.
            const StreetScan first = street_scan(0, 0.05f);
            for (const Part* part : {&scan.car, &scan.pedestrian, &scan.far_car}) {
                const Part& same = part == &scan.car          ? first.car
                                   : part == &scan.pedestrian ? first.pedestrian
                                                              : first.far_car;
                for (std::size_t i = 0; i < part->end - part->begin; ++i) {
                    scan.points[part->begin + i] = first.points[same.begin + i];
                }
            }
            scans.push_back(std::move(scan));
        }
        MovingObjectStats stats;
        const auto moving = moving_of(scans, MovingObjectConfig{}, &stats);
        EXPECT_EQ(stats.moving_objects, 0u) << length << " scans";
        for (const auto& flags : moving) {
            for (std::uint8_t f : flags) ASSERT_EQ(f, 0);
        }
    }
}

TEST(MovingObjects, OffOrASingleScanFlagsNothingAndBadSettingsAreNamed) {
    std::vector<StreetScan> scans;
    for (int s = 0; s < 12; ++s) scans.push_back(street_scan(s, 0.0f));
    MovingObjectConfig off;
    off.enabled = false;
    for (const auto& flags : moving_of(scans, off)) {
        for (std::uint8_t f : flags) ASSERT_EQ(f, 0);
    }
    const std::vector<StreetScan> one(scans.begin(), scans.begin() + 1);
    const auto single = moving_of(one, MovingObjectConfig{});
    ASSERT_EQ(single.size(), 1u);
    EXPECT_EQ(single[0].size(), one[0].points.size());

    const auto message_of = [&](const MovingObjectConfig& config) -> std::string {
        try {
            moving_of(scans, config);
        } catch (const ConfigError& e) {
            return e.what();
        }
        return "";
    };
    MovingObjectConfig bad;
    bad.window_scans = 0;
    EXPECT_NE(message_of(bad).find("dynamic.motion_window_scans"), std::string::npos);
    bad = MovingObjectConfig{};
    bad.match_m = 0.0f;
    EXPECT_NE(message_of(bad).find("dynamic.motion_match_m"), std::string::npos);
    bad = MovingObjectConfig{};
    bad.link_share = 1.5f;
    EXPECT_NE(message_of(bad).find("dynamic.motion_link_share"), std::string::npos);
    std::vector<const std::vector<Eigen::Vector3f>*> missing = {&scans[0].points, nullptr};
    EXPECT_THROW(find_moving_points(missing, DynamicObjectConfig{}, MovingObjectConfig{}),
                 DataError);
}

TEST(MovingObjects, LongSequencesGoInChunksAndLoseNothingAtTheirBorders) {
    // 150 scans: three chunks of 64 scans with their margins; the car drives on across the
    // chunks' borders (scans 63 / 64 and 127 / 128).
    std::vector<StreetScan> scans;
    for (int s = 0; s < 150; ++s) scans.push_back(street_scan(s, 0.03f));
    MovingObjectStats stats;
    const auto moving = moving_of(scans, MovingObjectConfig{}, &stats);
    for (std::size_t s = 0; s < scans.size(); ++s) {
        SCOPED_TRACE("scan " + std::to_string(s));
        EXPECT_EQ(count(moving[s], scans[s].car), above_ground(scans[s], scans[s].car));
        // Past the ground's end (x = 40 m, scan 57) the far car's lowest return is its ground.
        if (s < 56) {
            EXPECT_EQ(count(moving[s], scans[s].far_car), 4u);
        }
        EXPECT_EQ(count(moving[s], scans[s].parked_a) + count(moving[s], scans[s].parked_b) +
                      count(moving[s], scans[s].wall) + count(moving[s], scans[s].pedestrian),
                  0u);
    }
    // Counted once per scan, although the margins' scans are searched twice.
    EXPECT_EQ(stats.moving_objects, 2 * scans.size());
}

TEST(MovingObjects, WhileScansArriveTheScansBeforeTellTheMovers) {
    // Incremental mode: each new scan against the five before it. From the fourth scan on (three
    // scans before it, min_window_scans) the car and the far car move; nothing static does, and
    // after clear() the history starts again. The car drives at 2 m a scan here: a box seen
    // whole at 1.3 m a scan matches its place in the scan before on over 70 % of its points (its
    // long sides slide along themselves), so no velocity is searched for it; batch mode reaches it
    // from the one scan where it shows (the first test), which the scans before alone cannot.
    std::vector<StreetScan> scans;
    for (int s = 0; s < 12; ++s) scans.push_back(street_scan(s, 0.03f, 2.0f));
    PastMotion motion(DynamicObjectConfig{}, MovingObjectConfig{});
    for (std::size_t s = 0; s < scans.size(); ++s) {
        SCOPED_TRACE("scan " + std::to_string(s));
        if (s == 8) motion.clear();
        const std::size_t before = s < 8 ? s : s - 8;
        MovingObjectStats stats;
        const std::vector<std::uint8_t> flags = motion.add_scan(scans[s].points, &stats);
        ASSERT_EQ(flags.size(), scans[s].points.size());
        const StreetScan& scan = scans[s];
        if (before >= 3) {
            EXPECT_EQ(count(flags, scan.car), above_ground(scan, scan.car));
            EXPECT_EQ(count(flags, scan.far_car), 4u);
            EXPECT_EQ(stats.moving_objects, 2u);
        } else {
            EXPECT_EQ(stats.moving_objects, 0u);
        }
        EXPECT_EQ(count(flags, scan.ground) + count(flags, scan.parked_a) +
                      count(flags, scan.parked_b) + count(flags, scan.wall) +
                      count(flags, scan.pedestrian),
                  0u);
    }
    MovingObjectConfig off;
    off.enabled = false;
    PastMotion none(DynamicObjectConfig{}, off);
    for (const StreetScan& scan : scans) {
        for (std::uint8_t f : none.add_scan(scan.points)) ASSERT_EQ(f, 0);
    }
    MovingObjectConfig bad;
    bad.min_window_scans = 0;
    EXPECT_THROW(PastMotion(DynamicObjectConfig{}, bad), ConfigError);
}

TEST(MovingObjects, TheResultDoesNotDependOnTheRun) {
    std::vector<StreetScan> scans;
    for (int s = 0; s < 12; ++s) scans.push_back(street_scan(s, 0.03f));
    EXPECT_EQ(moving_of(scans, MovingObjectConfig{}), moving_of(scans, MovingObjectConfig{}));
}
