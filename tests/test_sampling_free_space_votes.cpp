// The range image and the dynamic-point votes on hand-made geometry: a wall behind the place of a
// box that one scan sees and the next does not.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/core/random.hpp"
#include "shine/sampling/free_space_votes.hpp"
#include "shine/sampling/range_image.hpp"

namespace shine {
namespace {

constexpr float kPi = 3.14159265358979f;

/// A spinning LiDAR at the origin: 32 rings from
/// -15 to +15 deg, 720 columns, ranges from `range_of(direction)` (0 = no return).
template <typename RangeFn>
std::vector<Eigen::Vector3f> spin_scan(RangeFn range_of) {
    std::vector<Eigen::Vector3f> points;
    for (int ring = 0; ring < 32; ++ring) {
        const float el = (-15.0f + 30.0f * ring / 31.0f) * kPi / 180.0f;
        for (int col = 0; col < 720; ++col) {
            const float az = -kPi + (col + 0.5f) * 2.0f * kPi / 720.0f;
            const Eigen::Vector3f d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                    std::sin(el));
            const float r = range_of(d);
            if (r > 0.0f) points.push_back(r * d);
        }
    }
    return points;
}

/// Range to the plane x = wall_x_m along d (directions within 60 deg of +x), else 0.
float wall_range(const Eigen::Vector3f& d, float wall_x_m) {
    return d.x() > 0.5f ? wall_x_m / d.x() : 0.0f;
}

/// Range to the wall, or to a box face x = box_x_m where |y|, |z| < half_m in front of it.
float wall_and_box_range(const Eigen::Vector3f& d, float wall_x_m, float box_x_m, float half_m) {
    if (d.x() <= 0.5f) return 0.0f;
    const float t = box_x_m / d.x();
    const Eigen::Vector3f p = t * d;
    if (std::abs(p.y()) < half_m && std::abs(p.z()) < half_m) return t;
    return wall_x_m / d.x();
}

TEST(RangeImage, BinsFollowTheScanDensityAndKeepTheNearestReturn) {
    const auto scan = spin_scan([](const Eigen::Vector3f& d) { return wall_range(d, 10.0f); });
    const RangeImage image(scan);
    // A third of the turn has returns, over 30 deg: the bin holds about one return.
    const float expected_rad = std::sqrt((30.0f * kPi / 180.0f) * 2.0f * kPi / scan.size());
    EXPECT_NEAR(image.bin_rad(), expected_rad, 0.02f * expected_rad);
    const RangeLookup ahead = image.nearest_around(Eigen::Vector3f(1.0f, 0.0f, 0.0f), 1);
    ASSERT_GT(ahead.returns, 0);
    EXPECT_NEAR(ahead.min_range_m, 10.0f, 0.05f);
    // Behind the sensor nothing returned; above the top ring is outside the image.
    EXPECT_EQ(image.nearest_around(Eigen::Vector3f(-1.0f, 0.0f, 0.0f), 1).returns, 0);
    EXPECT_EQ(image.nearest_around(Eigen::Vector3f(1.0f, 0.0f, 1.0f), 1).returns, 0);
    EXPECT_TRUE(RangeImage(std::vector<Eigen::Vector3f>{}).empty());
}

TEST(RangeImage, PreparedWindowGivesTheBinByBinLookup) {
    // Holes (no return), a box nearer than the wall, the seam at azimuth +-pi, directions above
    // and below the image and in the rows just outside it, and a tiny scan narrower than the
    // window: the prepared window must give the same nearest return and count as the bin walk.
    const auto scan = spin_scan([](const Eigen::Vector3f& d) {
        if (std::sin(37.0f * d.x()) * std::cos(23.0f * d.z()) > 0.6f) return 0.0f;  // holes
        return d.x() > 0.5f ? wall_and_box_range(d, 12.0f, 6.0f, 1.0f)
                            : 8.0f + 3.0f * std::abs(d.y());
    });
    const std::vector<Eigen::Vector3f> tiny{
        {1.0f, 0.0f, 0.0f}, {0.0f, 2.0f, 0.1f}, {-3.0f, 0.1f, -0.2f}};
    Pcg32 rng(7);
    int checked_returns[2] = {0, 0};  // lookups without and with returns in their window
    for (const auto* points : {&scan, &tiny}) {
        for (const int radius : {0, 1, 2, 5}) {
            RangeImage image(*points);
            image.prepare_window(radius);
            ASSERT_EQ(image.window_radius_bins(), radius);
            for (int i = 0; i < 20000; ++i) {
                const float az = (2.0f * rng.uniform() - 1.0f) * kPi;
                const float el = (2.0f * rng.uniform() - 1.0f) * 25.0f * kPi / 180.0f;
                const Eigen::Vector3f d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                        std::sin(el));
                const RangeLookup fast = image.nearest_around(d, radius);
                const RangeLookup plain = image.nearest_around_bins(d, radius);
                ASSERT_EQ(fast.returns, plain.returns) << "radius " << radius << " draw " << i;
                ASSERT_EQ(fast.min_range_m, plain.min_range_m) << "radius " << radius;
                ++checked_returns[fast.returns > 0];
            }
            // Another radius than the prepared one walks the bins.
            const Eigen::Vector3f ahead(1.0f, 0.0f, 0.0f);
            EXPECT_EQ(image.nearest_around(ahead, radius + 1).returns,
                      image.nearest_around_bins(ahead, radius + 1).returns);
        }
    }
    // Both cases occurred: directions with returns in their window and without.
    EXPECT_GT(checked_returns[0], 1000);
    EXPECT_GT(checked_returns[1], 1000);
    // An impossible radius prepares nothing.
    RangeImage image(scan);
    image.prepare_window(-1);
    EXPECT_EQ(image.window_radius_bins(), -1);
}

TEST(RangeImage, FastArctangentStaysWithinItsBound) {
    // Directions of every octant and magnitude ratio, from 1e-4 m to 1e4 m: the largest
    // difference to std::atan2 must stay far below the bound the lookups rely on.
    Pcg32 rng(45);
    float largest_rad = 0.0f;
    for (int i = 0; i < 4000000; ++i) {
        const float x =
            (2.0f * rng.uniform() - 1.0f) * std::pow(10.0f, 8.0f * rng.uniform() - 4.0f);
        const float y =
            (2.0f * rng.uniform() - 1.0f) * std::pow(10.0f, 8.0f * rng.uniform() - 4.0f);
        largest_rad = std::max(largest_rad,
                               std::abs(range_image_internal::fast_atan2(y, x) - std::atan2(y, x)));
    }
    // The axes and diagonals, where the octant logic switches.
    for (const float x : {-2.0f, -1.0f, -0.0f, 0.0f, 1.0f, 3.0f}) {
        for (const float y : {-2.0f, -1.0f, 0.0f, 1.0f, 3.0f}) {
            if (x == 0.0f && y == 0.0f) continue;
            largest_rad = std::max(
                largest_rad, std::abs(range_image_internal::fast_atan2(y, x) - std::atan2(y, x)));
        }
    }
    EXPECT_LT(largest_rad, range_image_internal::kFastAngleErrorRad / 20.0f);
}

TEST(RangeImage, LookupsOnBinEdgesFindStdAtan2sBins) {
    // An image with a different range in every bin and a window of one bin (radius 0): a lookup
    // in another bin than std::atan2's would read another range. Directions drawn at random and
    // directions exactly on (and a few float steps beside) the column and row edges, where the
    // lookups must fall back to std::atan2.
    std::vector<Eigen::Vector3f> scan;
    Pcg32 rng(46);
    for (int ring = 0; ring < 64; ++ring) {
        const float el = (-24.8f + 26.8f * ring / 63.0f) * kPi / 180.0f;
        for (int col = 0; col < 1800; ++col) {
            const float az = -kPi + (col + rng.uniform()) * 2.0f * kPi / 1800.0f;
            const Eigen::Vector3f d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                    std::sin(el));
            scan.push_back((2.0f + 60.0f * rng.uniform()) * d);
        }
    }
    RangeImage image(scan);
    image.prepare_window(0);
    ASSERT_EQ(image.window_radius_bins(), 0);
    float el_min_rad = 10.0f;
    for (const Eigen::Vector3f& p : scan) {
        el_min_rad = std::min(el_min_rad, std::atan2(p.z(), std::hypot(p.x(), p.y())));
    }
    const float bin_rad = image.bin_rad();
    int compared = 0, with_return = 0;
    const auto compare = [&](float az, float el, float scale) {
        const Eigen::Vector3f d =
            scale *
            Eigen::Vector3f(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
        const RangeLookup fast = image.nearest_around(d, 0);
        const RangeLookup plain = image.nearest_around_bins(d, 0);
        ASSERT_EQ(fast.returns, plain.returns) << az << " " << el;
        ASSERT_EQ(fast.min_range_m, plain.min_range_m) << az << " " << el;
        ++compared;
        with_return += fast.returns > 0;
    };
    for (int i = 0; i < 200000; ++i) {
        compare((2.0f * rng.uniform() - 1.0f) * kPi, (2.0f * rng.uniform() - 1.0f) * 0.5f,
                0.1f + 50.0f * rng.uniform());
    }
    for (int col = 0; col <= image.cols(); col += 7) {
        for (int row = -2; row <= image.rows() + 2; row += 3) {
            float az = -kPi + col * bin_rad;
            float el = el_min_rad + row * bin_rad;
            for (int step = 0; step < 3; ++step) {
                az = std::nextafter(az, -10.0f);
                el = std::nextafter(el, -10.0f);
            }
            for (int step = 0; step < 7; ++step) {
                compare(az, el, 1.0f + step);
                compare(az, el + 0.5f * bin_rad, 1.0f);
                compare(az + 0.5f * bin_rad, el, 1.0f);
                az = std::nextafter(az, 10.0f);
                el = std::nextafter(el, 10.0f);
            }
        }
    }
    EXPECT_GT(compared, 300000);
    EXPECT_GT(with_return, compared / 4);
}

TEST(RangeImage, FastAnglesBuildTheImageOfStdAtan2) {
    // 64 rings at jittered elevations and azimuths, returns at random ranges (so that a return in
    // another bin shows), and a few odd points (on the axis, tiny, huge, not finite): the image
    // equals the one built with std::atan2 for every return, bin for bin. (The points on the
    // axis stretch the image from -90 to +90 deg.)
    Pcg32 rng(47);
    for (const int columns : {1800, 1024, 361}) {
        std::vector<Eigen::Vector3f> scan;
        for (int ring = 0; ring < 64; ++ring) {
            for (int col = 0; col < columns; ++col) {
                const float el =
                    (-24.8f + 26.8f * (ring + 0.3f * rng.uniform()) / 63.0f) * kPi / 180.0f;
                const float az = -kPi + (col + rng.uniform()) * 2.0f * kPi / columns;
                const Eigen::Vector3f d(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                        std::sin(el));
                scan.push_back((2.0f + 60.0f * rng.uniform()) * d);
            }
        }
        scan.emplace_back(0.0f, 0.0f, 3.0f);
        scan.emplace_back(0.0f, 0.0f, -3.0f);
        scan.emplace_back(1e-20f, -1e-20f, 1e-20f);
        scan.emplace_back(1e20f, 3e19f, -1e19f);
        scan.emplace_back(std::nanf(""), 1.0f, 0.0f);
        scan.emplace_back(-4.0f, -0.0f, 0.0f);
        // Returns exactly on (and a few float steps beside) bin edges, where the fast angles
        // must give way to std::atan2's: placed by an image of as many returns (the bins follow
        // the count), with the span of elevations they do not change.
        constexpr int kEdgeReturns = 3000;
        const std::size_t before = scan.size();
        scan.resize(before + kEdgeReturns, scan.front());
        const RangeImage sizing(scan, true);
        float el_min_rad = 10.0f;
        for (std::size_t i = 0; i < before; ++i) {  // as the image's lowest elevation
            const Eigen::Vector3f& p = scan[i];
            if (!p.allFinite() || !(p.norm() >= 1e-6f)) continue;
            el_min_rad = std::min(el_min_rad, std::atan2(p.z(), std::hypot(p.x(), p.y())));
        }
        for (int k = 0; k < kEdgeReturns; ++k) {
            const int col = static_cast<int>(rng.uniform() * (sizing.cols() - 1)) + 1;
            const int row = static_cast<int>(rng.uniform() * (sizing.rows() - 2)) + 1;
            float az = -kPi + col * sizing.bin_rad();
            float el = el_min_rad + row * sizing.bin_rad();
            for (int step = static_cast<int>(rng.uniform() * 7.0f) - 3; step != 0;
                 step += step > 0 ? -1 : 1) {
                az = std::nextafter(az, step > 0 ? 10.0f : -10.0f);
                el = std::nextafter(el, step > 0 ? 10.0f : -10.0f);
            }
            scan[before + k] = (2.0f + 60.0f * rng.uniform()) *
                               Eigen::Vector3f(std::cos(el) * std::cos(az),
                                               std::cos(el) * std::sin(az), std::sin(el));
        }
        const RangeImage fast(scan);
        const RangeImage reference(scan, true);
        ASSERT_EQ(fast.rows(), reference.rows());
        ASSERT_EQ(fast.cols(), reference.cols());
        ASSERT_EQ(fast.bin_rad(), reference.bin_rad());
        int compared = 0;
        const float bin_rad = reference.bin_rad();
        for (int row = -1; row <= reference.rows(); ++row) {
            for (int col = 0; col < reference.cols(); ++col) {
                // Three directions across each bin of the nominal rings' span: equal images
                // answer every direction alike.
                for (const float at : {0.25f, 0.5f, 0.75f}) {
                    const float az = -kPi + (col + at) * bin_rad;
                    const float el = -24.8f * kPi / 180.0f + (row + at) * bin_rad;
                    const Eigen::Vector3f d(std::cos(el) * std::cos(az),
                                            std::cos(el) * std::sin(az), std::sin(el));
                    const RangeLookup a = fast.nearest_around_bins(d, 0);
                    const RangeLookup b = reference.nearest_around_bins(d, 0);
                    ASSERT_EQ(a.returns, b.returns) << row << " " << col;
                    ASSERT_EQ(a.min_range_m, b.min_range_m) << row << " " << col;
                    compared += b.returns;
                }
            }
        }
        EXPECT_GT(compared, columns * 64 / 3);  // 46 % measured: the bins with a return
    }
}

TEST(FreeSpaceVotes, ABoxThatLeftIsSeenThroughAndTheWallIsNot) {
    constexpr float kWallM = 12.0f, kBoxM = 6.0f, kHalfM = 1.0f;
    const auto with_box = spin_scan(
        [](const Eigen::Vector3f& d) { return wall_and_box_range(d, kWallM, kBoxM, kHalfM); });
    const auto without_box =
        spin_scan([](const Eigen::Vector3f& d) { return wall_range(d, kWallM); });
    const RangeImage image_without(without_box);
    const RangeImage image_with(with_box);

    DynamicPointConfig config;
    const Eigen::Isometry3f T_sensor_map = Eigen::Isometry3f::Identity();
    // Points of the scan with the box, voted on by the scan without it.
    std::vector<FreeSpaceVotes> votes(with_box.size());
    add_free_space_votes(image_without, T_sensor_map, with_box.data(), with_box.size(), config,
                         votes.data());
    int box_free = 0, box_points = 0, wall_free = 0, wall_hit = 0, wall_points = 0;
    for (std::size_t i = 0; i < with_box.size(); ++i) {
        if (with_box[i].x() < kBoxM + 0.01f) {
            ++box_points;
            box_free += votes[i].free;
        } else {
            ++wall_points;
            wall_free += votes[i].free;
            wall_hit += votes[i].hit;
        }
    }
    ASSERT_GT(box_points, 20);
    // Every box point lies in front of the wall the other scan measured: seen through. Points at
    // the box's rim see wall returns only (the window's nearest is the wall, 6 m beyond).
    EXPECT_EQ(box_free, box_points);
    EXPECT_EQ(wall_free, 0);
    // The rest of the wall is hit, but for 3 % at the grazing sides (azimuth 53-60 deg), where the
    // window's nearest return is a neighbour's, metres closer: hidden, no vote (measured 6664 of
    // 6868).
    EXPECT_GT(wall_hit, 0.95 * wall_points);

    // The other way round: the wall points the box hid are occluded for the scan with the box
    // (no vote), the rest are hits; none is free.
    std::vector<FreeSpaceVotes> back(without_box.size());
    add_free_space_votes(image_with, T_sensor_map, without_box.data(), without_box.size(), config,
                         back.data());
    int free_votes = 0, hidden = 0;
    for (const FreeSpaceVotes& v : back) {
        free_votes += v.free;
        hidden += v.free + v.hit == 0;
    }
    EXPECT_EQ(free_votes, 0);
    EXPECT_GT(hidden, box_points / 2);
}

TEST(FreeSpaceVotes, AMovedSensorVotesThroughItsPose) {
    // The scan without the box taken 2 m to the left (+y): its image in its own frame, the box
    // points moved into that frame by T_sensor_map.
    constexpr float kWallM = 12.0f, kBoxM = 6.0f, kHalfM = 1.0f;
    const auto with_box = spin_scan(
        [](const Eigen::Vector3f& d) { return wall_and_box_range(d, kWallM, kBoxM, kHalfM); });
    const RangeImage moved(
        spin_scan([](const Eigen::Vector3f& d) { return wall_range(d, kWallM); }));
    Eigen::Isometry3f T_sensor_map = Eigen::Isometry3f::Identity();
    T_sensor_map.translation() = Eigen::Vector3f(0.0f, -2.0f, 0.0f);  // sensor at y = +2 m
    std::vector<FreeSpaceVotes> votes(with_box.size());
    add_free_space_votes(moved, T_sensor_map, with_box.data(), with_box.size(),
                         DynamicPointConfig{}, votes.data());
    for (std::size_t i = 0; i < with_box.size(); ++i) {
        if (with_box[i].x() < kBoxM + 0.01f) {
            EXPECT_EQ(votes[i].free, 1) << "box point " << i;
        } else {
            EXPECT_EQ(votes[i].free, 0) << "wall point " << i;
        }
    }
}

TEST(FreeSpaceVotes, DynamicNeedsEnoughAndAShareOfFreeVotes) {
    DynamicPointConfig config;  // 2 votes, 40 %
    EXPECT_FALSE(is_dynamic({1, 0}, config));
    EXPECT_TRUE(is_dynamic({2, 0}, config));
    EXPECT_TRUE(is_dynamic({4, 6}, config));   // 40 %
    EXPECT_FALSE(is_dynamic({3, 7}, config));  // 30 %
    EXPECT_FALSE(is_dynamic({2, 8}, config));  // 20 %
    EXPECT_FALSE(is_dynamic({0, 0}, config));
    config.min_free_share = 0.0f;
    EXPECT_THROW(check_dynamic_point_config(config), ConfigError);
    config = {};
    config.margin_m = 0.0f;
    EXPECT_THROW(check_dynamic_point_config(config), ConfigError);
    config = {};
    config.far_min_free_share = 0.0f;
    EXPECT_THROW(check_dynamic_point_config(config), ConfigError);
    config = {};
    config.far_vote_frames = -1;
    EXPECT_THROW(check_dynamic_point_config(config), ConfigError);
}

TEST(FreeSpaceVotes, FarVotesCountOnlyForPointsTheNearScansHardlyHit) {
    DynamicPointConfig config;  // far: at most 1 near hit, 2 far free votes, 50 % of far votes
    const auto votes = [](int free, int hit, int far_free, int far_hit) {
        FreeSpaceVotes v;
        v.free = static_cast<std::uint16_t>(free);
        v.hit = static_cast<std::uint16_t>(hit);
        v.far_free = static_cast<std::uint16_t>(far_free);
        v.far_hit = static_cast<std::uint16_t>(far_hit);
        return v;
    };
    EXPECT_TRUE(is_dynamic(votes(0, 0, 2, 2), config));  // an oncoming car seen far ahead
    EXPECT_TRUE(is_dynamic(votes(1, 1, 3, 1), config));
    EXPECT_FALSE(is_dynamic(votes(0, 2, 5, 0), config));  // the near scans hit it: static
    EXPECT_FALSE(is_dynamic(votes(0, 0, 2, 3), config));  // 40 % of the far votes
    EXPECT_FALSE(is_dynamic(votes(0, 0, 1, 0), config));  // one far scan is not enough
    config.far_max_near_hits = 2;
    EXPECT_TRUE(is_dynamic(votes(0, 2, 5, 0), config));

    // add_free_space_votes counts far votes apart: a scan that sees a wall 5 m behind a point.
    const RangeImage image(
        spin_scan([](const Eigen::Vector3f& d) { return wall_range(d, 10.0f); }));
    const std::vector<Eigen::Vector3f> point = {{5.0f, 0.0f, 0.0f}};
    std::vector<FreeSpaceVotes> v(1);
    add_free_space_votes(image, Eigen::Isometry3f::Identity(), point.data(), 1, config, v.data(),
                         true);
    EXPECT_EQ(v[0].far_free, 1);
    EXPECT_EQ(v[0].free, 0);
    add_free_space_votes(image, Eigen::Isometry3f::Identity(), point.data(), 1, config, v.data());
    EXPECT_EQ(v[0].free, 1);
}

}  // namespace
}  // namespace shine
