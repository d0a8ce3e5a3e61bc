// The kept replay set (replay_rays.hpp) against the set assembled afresh from the window, as the
// incremental mapper assembled it before: through a window that grows, slides, has the scans at
// its end thinned and their normals changed, is restored empty, and asks for fewer scans than
// it holds. Also RaySet's truncate(), erase_front() and keep_rays() against sets built from the
// kept scans.
#include <gtest/gtest.h>

#include <algorithm>
#include <deque>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/core/random.hpp"
#include "shine/geometry/voxel_groups.hpp"
#include "shine/mapper/replay_rays.hpp"
#include "shine/sampling/ray_set.hpp"

namespace shine {
namespace {

ScanInMap random_scan(Pcg32& rng, int max_points) {
    ScanInMap scan;
    scan.origin_map = Eigen::Vector3f(rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(0, 2));
    const int n = static_cast<int>(rng.below64(static_cast<std::uint64_t>(max_points) + 1));
    for (int i = 0; i < n; ++i) {
        scan.points_map.emplace_back(rng.uniform(-20, 20), rng.uniform(-20, 20),
                                     rng.uniform(-2, 5));
    }
    return scan;
}

std::vector<Eigen::Vector3f> random_normals(Pcg32& rng, std::size_t n) {
    std::vector<Eigen::Vector3f> normals;
    for (std::size_t i = 0; i < n; ++i) {
        normals.push_back(Eigen::Vector3f(rng.uniform(-1, 1), rng.uniform(-1, 1), 1).normalized());
    }
    return normals;
}

/// The live rays of `replay` equal, ray by ray, the last `replayed` scans of the window added
/// afresh to an empty set (zero normals where a scan's normals do not match its points).
void expect_live_rays_equal_fresh(const ReplayRays& replay, const std::deque<ScanInMap>& window,
                                  const std::deque<std::vector<Eigen::Vector3f>>& normals,
                                  std::size_t replayed) {
    RaySet fresh;
    const std::size_t n = window.size();
    const std::size_t first = n - std::min(n, replayed);
    for (std::size_t w = first; w < n; ++w) {
        const bool with = normals[w].size() == window[w].points_map.size();
        fresh.add_scan_with_normals(window[w].origin_map, window[w].points_map,
                                    with ? normals[w] : std::vector<Eigen::Vector3f>{});
    }
    const RaySet& kept = replay.rays();
    const std::size_t begin = replay.begin_ray();
    ASSERT_EQ(kept.num_rays() - begin, fresh.num_rays());
    ASSERT_EQ(replay.live_scans(), fresh.num_scans());
    for (std::size_t r = 0; r < fresh.num_rays(); ++r) {
        ASSERT_EQ(kept.endpoint(begin + r), fresh.endpoint(r)) << "ray " << r;
        ASSERT_EQ(kept.normal(begin + r), fresh.normal(r)) << "ray " << r;
        ASSERT_EQ(kept.origin_of_ray(begin + r), fresh.origin_of_ray(r)) << "ray " << r;
    }
    if (fresh.num_scans() > 0) {
        const auto last = static_cast<std::uint32_t>(fresh.num_scans() - 1);
        EXPECT_EQ(replay.last_scan_begin_ray() - begin, fresh.first_ray(last));
    }
}

TEST(ReplayRays, KeptSetEqualsTheFreshSetThroughASlidingThinnedWindow) {
    Pcg32 rng(5);
    for (const std::size_t replayed : {1u, 3u, 12u}) {
        const std::size_t window_frames = std::max<std::size_t>(replayed, 5);
        const std::size_t changed_tail = 4;  // the filter thins the 3 scans before the new one
        std::deque<ScanInMap> window;
        std::deque<std::vector<Eigen::Vector3f>> normals;
        std::uint64_t first_serial = 0;
        ReplayRays replay;
        for (int frame = 0; frame < 60; ++frame) {
            // The filter thins the last scans of the window and their normals alike.
            for (std::size_t k = 1; k < changed_tail && k <= window.size(); ++k) {
                const std::size_t w = window.size() - k;
                std::vector<Eigen::Vector3f>& points = window[w].points_map;
                const std::size_t keep = points.empty() ? 0 : rng.below64(points.size() + 1);
                points.resize(keep);
                if (!normals[w].empty()) normals[w].resize(keep);
            }
            window.push_back(random_scan(rng, 40));
            // Some scans have no normals (restored without replay): zero normals.
            normals.push_back(frame % 7 == 3
                                  ? std::vector<Eigen::Vector3f>{}
                                  : random_normals(rng, window.back().points_map.size()));
            while (window.size() > window_frames) {
                window.pop_front();
                normals.pop_front();
                ++first_serial;
            }
            if (frame == 30) replay.clear();  // a restored state
            replay.sync(window, normals, first_serial, replayed, changed_tail);
            expect_live_rays_equal_fresh(replay, window, normals, replayed);
            if (HasFatalFailure()) return;
            // A second sync with nothing changed keeps the set as it is.
            replay.sync(window, normals, first_serial, replayed, 0);
            expect_live_rays_equal_fresh(replay, window, normals, replayed);
            if (HasFatalFailure()) return;
        }
        // The dead prefix was cut away as it grew: at most a quarter of the live rays remain.
        EXPECT_LE(4 * replay.begin_ray(), replay.rays().num_rays() - replay.begin_ray() + 4 * 40);
        // Assembled from nothing only at the first scan and after the restore.
        EXPECT_EQ(replay.rebuilds(), 2u);
    }
}

TEST(RaySet, TruncateAndEraseFrontKeepTheOtherScansAsAddedAfresh) {
    Pcg32 rng(9);
    std::vector<ScanInMap> scans;
    for (int s = 0; s < 6; ++s) scans.push_back(random_scan(rng, 30));
    scans[2].points_map.clear();  // a scan without rays
    for (const bool grouped : {false, true}) {
        const auto build = [&](std::size_t from, std::size_t to) {
            RaySet set;
            for (std::size_t s = from; s < to; ++s) {
                std::vector<std::uint32_t> voxels;
                if (grouped && !scans[s].points_map.empty()) {
                    for (std::uint32_t i = 0; i < scans[s].points_map.size(); i += 3) {
                        voxels.push_back(i);
                    }
                }
                set.add_scan(scans[s].origin_map, scans[s].points_map, voxels);
            }
            return set;
        };
        const auto expect_equal = [](const RaySet& a, const RaySet& b) {
            ASSERT_EQ(a.num_rays(), b.num_rays());
            ASSERT_EQ(a.num_scans(), b.num_scans());
            ASSERT_EQ(a.num_groups(), b.num_groups());
            for (std::uint32_t s = 0; s <= a.num_scans(); ++s) {
                EXPECT_EQ(a.first_ray(s), b.first_ray(s));
            }
            for (std::size_t r = 0; r < a.num_rays(); ++r) {
                EXPECT_EQ(a.endpoint(r), b.endpoint(r));
                EXPECT_EQ(a.scan_of_ray(r), b.scan_of_ray(r));
                EXPECT_EQ(a.origin_of_ray(r), b.origin_of_ray(r));
            }
            for (std::size_t g = 0; g <= a.num_groups(); ++g) {
                EXPECT_EQ(a.first_ray_of_group(g), b.first_ray_of_group(g));
            }
        };
        for (std::uint32_t k = 0; k <= 6; ++k) {
            RaySet front = build(0, 6);
            front.erase_front(k);
            expect_equal(front, build(k, 6));
            RaySet back = build(0, 6);
            back.truncate(k);
            expect_equal(back, build(0, k));
            // Scans added after a truncation follow on as in a fresh set.
            back.add_scan(scans[5].origin_map, scans[5].points_map);
            RaySet again = build(0, k);
            again.add_scan(scans[5].origin_map, scans[5].points_map);
            expect_equal(back, again);
        }
    }
}

TEST(RaySet, KeepRaysInPlaceEqualsTheKeptRaysAddedAfresh) {
    // keep_rays() against each scan's kept rays filtered by filter_voxel_grouped() and added to
    // a new set: grouped and not, with and without an origin per ray, a scan without rays, a
    // scan that loses every ray and runs that lose every ray.
    Pcg32 rng(21);
    std::vector<ScanInMap> scans;
    for (int s = 0; s < 7; ++s) scans.push_back(random_scan(rng, 40));
    scans[2].points_map.clear();
    for (const bool grouped : {false, true}) {
        for (const bool with_origins : {false, true}) {
            std::vector<std::vector<std::uint32_t>> voxels(scans.size());
            std::vector<std::vector<Eigen::Vector3f>> origins(scans.size());
            RaySet set;
            for (std::size_t s = 0; s < scans.size(); ++s) {
                const std::size_t n = scans[s].points_map.size();
                if (grouped && n > 0) {
                    for (std::uint32_t i = 0; i < n;
                         i += 1 + static_cast<std::uint32_t>(rng.below64(4))) {
                        voxels[s].push_back(i);
                    }
                }
                if (with_origins && s % 2 == 1) {
                    for (std::size_t i = 0; i < n; ++i) {
                        origins[s].push_back(Eigen::Vector3f(float(s), float(i), 0.5f));
                    }
                }
                set.add_scan(scans[s].origin_map, scans[s].points_map, voxels[s], origins[s]);
            }
            std::vector<std::uint8_t> keep(set.num_rays());
            for (std::size_t r = 0; r < keep.size(); ++r) {
                const std::uint32_t s = set.scan_of_ray(r);
                keep[r] = s == 4 ? 0 : (rng.below64(3) != 0);
            }
            RaySet fresh;
            std::size_t removed = 0;
            for (std::uint32_t s = 0; s < set.num_scans(); ++s) {
                const std::size_t begin = set.first_ray(s);
                std::vector<Eigen::Vector3f> points = scans[s].points_map;
                std::vector<std::uint32_t> runs = voxels[s];
                std::vector<Eigen::Vector3f> ray_origins;
                if (set.has_ray_origins()) {
                    for (std::size_t i = 0; i < points.size(); ++i) {
                        ray_origins.push_back(set.origin_of_ray(begin + i));
                    }
                }
                removed += filter_voxel_grouped(
                    points, runs, [&](std::size_t i, std::size_t) { return keep[begin + i] != 0; },
                    &ray_origins);
                fresh.add_scan(set.origin_of_scan(s), points, runs, ray_origins);
            }
            EXPECT_EQ(set.keep_rays(keep), removed);
            ASSERT_EQ(set.num_rays(), fresh.num_rays());
            ASSERT_EQ(set.num_scans(), fresh.num_scans());
            ASSERT_EQ(set.num_groups(), fresh.num_groups());
            EXPECT_EQ(set.has_ray_origins(), fresh.has_ray_origins());
            for (std::uint32_t s = 0; s <= set.num_scans(); ++s) {
                EXPECT_EQ(set.first_ray(s), fresh.first_ray(s));
            }
            EXPECT_EQ(set.first_ray(5), set.first_ray(4));  // scan 4 lost every ray
            for (std::size_t r = 0; r < set.num_rays(); ++r) {
                EXPECT_EQ(set.endpoint(r), fresh.endpoint(r));
                EXPECT_EQ(set.scan_of_ray(r), fresh.scan_of_ray(r));
                EXPECT_EQ(set.origin_of_ray(r), fresh.origin_of_ray(r));
            }
            for (std::size_t g = 0; g <= set.num_groups(); ++g) {
                EXPECT_EQ(set.first_ray_of_group(g), fresh.first_ray_of_group(g));
            }
        }
    }
    RaySet set;
    set.add_scan(Eigen::Vector3f::Zero(), {{1, 0, 0}, {0, 1, 0}});
    EXPECT_THROW(set.keep_rays({1}), DataError);
}

TEST(RaySet, NormalsOfAScanMustMatchItsPoints) {
    RaySet set;
    const std::vector<Eigen::Vector3f> points{{1, 0, 0}, {0, 1, 0}};
    EXPECT_THROW(
        set.add_scan_with_normals(Eigen::Vector3f::Zero(), points, std::vector<Eigen::Vector3f>(3)),
        DataError);
    set.add_scan_with_normals(Eigen::Vector3f::Zero(), points, {});
    set.add_scan_with_normals(Eigen::Vector3f::Zero(), points,
                              {Eigen::Vector3f::UnitZ(), Eigen::Vector3f::UnitX()});
    EXPECT_EQ(set.normal(0), Eigen::Vector3f::Zero());  // the first scan had none
    EXPECT_EQ(set.normal(3), Eigen::Vector3f::UnitX());
}

TEST(RaySet, RayOriginsFollowTheirRaysThroughTruncateAndEraseFront) {
    // Scans 0 and 2 without ray origins (their rays start at the scan's origin), scan 1 with one
    // per ray; the set keeps each ray's origin as rays are cut from either end.
    const std::vector<Eigen::Vector3f> points{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    const std::vector<Eigen::Vector3f> ray_origins{{0.1f, 0, 0}, {0.2f, 0, 0}, {0.3f, 0, 0}};
    const Eigen::Vector3f o0(10, 0, 0), o1(20, 0, 0), o2(30, 0, 0);
    const auto build = [&] {
        RaySet set;
        set.add_scan(o0, points);
        EXPECT_FALSE(set.has_ray_origins());
        set.add_scan_with_normals(o1, points, {}, ray_origins);
        set.add_scan(o2, points);
        return set;
    };
    RaySet set = build();
    ASSERT_TRUE(set.has_ray_origins());
    EXPECT_EQ(set.origin_of_ray(0), o0);
    EXPECT_EQ(set.origin_of_ray(4), ray_origins[1]);
    EXPECT_EQ(set.origin_of_ray(8), o2);
    EXPECT_EQ(set.origin_of_scan(1), o1);
    set.erase_front(1);
    EXPECT_EQ(set.origin_of_ray(0), ray_origins[0]);
    EXPECT_EQ(set.origin_of_ray(5), o2);
    set.truncate(1);
    ASSERT_EQ(set.num_rays(), 3u);
    EXPECT_EQ(set.origin_of_ray(2), ray_origins[2]);
    set.clear();
    EXPECT_FALSE(set.has_ray_origins());
    set.add_scan(o0, points);
    EXPECT_EQ(set.origin_of_ray(1), o0);
    EXPECT_THROW(set.add_scan(o0, points, {}, std::vector<Eigen::Vector3f>(2)), DataError);
}

}  // namespace
}  // namespace shine
