// Moving objects: a compact object that the scans around it hold further on at a steady velocity,
// and the objects that carry on from it.
#include "shine/sampling/moving_objects.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <limits>
#include <memory>
#include <string>
#include <utility>

#include "shine/core/error.hpp"

namespace shine {
namespace {

constexpr std::int64_t kOffset = std::int64_t(1) << 20;
constexpr std::uint64_t kMask = (std::uint64_t(1) << 21) - 1;
constexpr std::uint32_t kNoObject = ScanObjects::kNoObject;
/// A cell that the grown cells of several objects share.
constexpr std::uint32_t kShared = kNoObject - 1;

std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
    return ((std::uint64_t(x + kOffset) & kMask) << 42) |
           ((std::uint64_t(y + kOffset) & kMask) << 21) | (std::uint64_t(z + kOffset) & kMask);
}

/// The cells of match_m around a scan's object points (each point's cell and the 26 around it),
/// with the object that covers each (kShared for several): open addressing, linear probing.
class CellTable {
  public:
    CellTable(const std::vector<Eigen::Vector3f>& points, const ScanObjects& objects, float cell_m)
        : inv_cell_(1.0f / cell_m) {
        std::size_t object_points = 0;
        for (std::uint32_t o : objects.object_of) object_points += o != kNoObject;
        // Neighbouring points share most of their 27 cells: room for 8 a point, grown when half
        // full.
        std::size_t capacity = 64;
        while (capacity < object_points * 8) capacity *= 2;
        keys_.assign(capacity, kEmpty);
        values_.assign(capacity, kNoObject);
        for (std::size_t i = 0; i < points.size(); ++i) {
            const std::uint32_t o = objects.object_of[i];
            if (o == kNoObject) continue;
            const std::array<std::int64_t, 3> c = cell_of(points[i]);
            for (std::int64_t dx = -1; dx <= 1; ++dx) {
                for (std::int64_t dy = -1; dy <= 1; ++dy) {
                    for (std::int64_t dz = -1; dz <= 1; ++dz) {
                        insert(pack(c[0] + dx, c[1] + dy, c[2] + dz), o);
                    }
                }
            }
        }
    }

    /// The object covering the cell of p (kShared for several), or kNoObject.
    std::uint32_t find(const Eigen::Vector3f& p) const {
        const std::array<std::int64_t, 3> c = cell_of(p);
        const std::uint64_t key = pack(c[0], c[1], c[2]);
        const std::size_t mask = keys_.size() - 1;
        for (std::size_t slot = hash(key) & mask;; slot = (slot + 1) & mask) {
            if (keys_[slot] == key) return values_[slot];
            if (keys_[slot] == kEmpty) return kNoObject;
        }
    }

  private:
    static constexpr std::uint64_t kEmpty = ~std::uint64_t(0);

    std::array<std::int64_t, 3> cell_of(const Eigen::Vector3f& p) const {
        return {std::int64_t(std::floor(p.x() * inv_cell_)),
                std::int64_t(std::floor(p.y() * inv_cell_)),
                std::int64_t(std::floor(p.z() * inv_cell_))};
    }
    static std::size_t hash(std::uint64_t key) {
        key ^= key >> 33;
        key *= 0xff51afd7ed558ccdULL;
        key ^= key >> 33;
        return static_cast<std::size_t>(key);
    }
    void insert(std::uint64_t key, std::uint32_t object) {
        if (2 * (size_ + 1) > keys_.size()) grow();
        const std::size_t mask = keys_.size() - 1;
        for (std::size_t slot = hash(key) & mask;; slot = (slot + 1) & mask) {
            if (keys_[slot] == kEmpty) {
                keys_[slot] = key;
                values_[slot] = object;
                ++size_;
                return;
            }
            if (keys_[slot] == key) {
                if (values_[slot] != object) values_[slot] = kShared;
                return;
            }
        }
    }
    void grow() {
        std::vector<std::uint64_t> keys(keys_.size() * 2, kEmpty);
        std::vector<std::uint32_t> values(keys.size(), kNoObject);
        const std::size_t mask = keys.size() - 1;
        for (std::size_t i = 0; i < keys_.size(); ++i) {
            if (keys_[i] == kEmpty) continue;
            std::size_t slot = hash(keys_[i]) & mask;
            while (keys[slot] != kEmpty) slot = (slot + 1) & mask;
            keys[slot] = keys_[i];
            values[slot] = values_[i];
        }
        keys_ = std::move(keys);
        values_ = std::move(values);
    }

    float inv_cell_ = 1.0f;
    std::size_t size_ = 0;
    std::vector<std::uint64_t> keys_;
    std::vector<std::uint32_t> values_;
};

/// One scan's objects: their points (indices into the scan, grouped by object) and boxes, and
/// the cells they cover.
struct TrackScan {
    ScanObjects objects;
    std::vector<std::uint32_t> begin;  ///< object o's points are order[begin[o], begin[o + 1])
    std::vector<std::uint32_t> order;
    std::vector<Eigen::Vector3f> lo, hi;
    CellTable table;

    TrackScan(const std::vector<Eigen::Vector3f>& points, ScanObjects scan_objects, float cell_m)
        : objects(std::move(scan_objects)), table(points, objects, cell_m) {
        const std::uint32_t n = objects.num_objects;
        begin.assign(n + 1, 0);
        for (std::uint32_t o : objects.object_of) {
            if (o != kNoObject) ++begin[o + 1];
        }
        for (std::uint32_t o = 0; o < n; ++o) begin[o + 1] += begin[o];
        order.resize(begin[n]);
        std::vector<std::uint32_t> next(begin.begin(), begin.end() - 1);
        lo.assign(n, Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity()));
        hi.assign(n, Eigen::Vector3f::Constant(-std::numeric_limits<float>::infinity()));
        for (std::uint32_t i = 0; i < objects.object_of.size(); ++i) {
            const std::uint32_t o = objects.object_of[i];
            if (o == kNoObject) continue;
            order[next[o]++] = i;
            lo[o] = lo[o].cwiseMin(points[i]);
            hi[o] = hi[o].cwiseMax(points[i]);
        }
    }
    std::uint32_t size(std::uint32_t o) const { return begin[o + 1] - begin[o]; }
    /// Object o's points, every one or evenly thinned to at most `at_most` (0: all).
    std::vector<Eigen::Vector3f> points_of(const std::vector<Eigen::Vector3f>& points,
                                           std::uint32_t o, std::size_t at_most) const {
        const std::size_t count = size(o);
        const std::size_t stride =
            at_most == 0 ? 1 : std::max<std::size_t>(1, (count + at_most - 1) / at_most);
        std::vector<Eigen::Vector3f> result;
        result.reserve(count / stride + 1);
        for (std::size_t k = 0; k < count; k += stride)
            result.push_back(points[order[begin[o] + k]]);
        return result;
    }
};

/// Share of `points` that land, shifted horizontally by `step`, on a cell of `table` covered by
/// `object` (by any object for kNoObject; a shared cell counts for every object).
float match_share(const std::vector<Eigen::Vector3f>& points, const Eigen::Vector2f& step,
                  const CellTable& table, std::uint32_t object = kNoObject) {
    if (points.empty()) return 0.0f;
    std::size_t matched = 0;
    for (const Eigen::Vector3f& p : points) {
        const std::uint32_t found =
            table.find(Eigen::Vector3f(p.x() + step.x(), p.y() + step.y(), p.z()));
        matched += object == kNoObject ? found != kNoObject : (found == object || found == kShared);
    }
    return static_cast<float>(matched) / static_cast<float>(points.size());
}

struct StepMatch {
    Eigen::Vector2f step = Eigen::Vector2f::Zero();
    float share = -1.0f;
};

/// Whether a step is better than another: a larger share, then the shorter step.
bool better(const StepMatch& a, const StepMatch& b) {
    if (a.share != b.share) return a.share > b.share;
    return a.step.squaredNorm() < b.step.squaredNorm();
}

/// The steps on the grid of `spacing` no longer than max_step_m and at least min_step_m long at
/// which at least min_match_share of `points` match on `table`, the best `at_most` first.
std::vector<StepMatch> good_steps(const std::vector<Eigen::Vector3f>& points,
                                  const CellTable& table, float spacing, std::size_t at_most,
                                  const MovingObjectConfig& config) {
    std::vector<StepMatch> found;
    const int cells = static_cast<int>(std::floor(config.max_step_m / spacing + 1e-4f));
    for (int i = -cells; i <= cells; ++i) {
        for (int j = -cells; j <= cells; ++j) {
            const Eigen::Vector2f step(static_cast<float>(i) * spacing,
                                       static_cast<float>(j) * spacing);
            const float length = step.norm();
            if (length > config.max_step_m + 1e-4f || length < config.min_step_m - 1e-4f) continue;
            const float share = match_share(points, step, table);
            if (share >= config.min_match_share) found.push_back({step, share});
        }
    }
    std::stable_sort(found.begin(), found.end(), better);
    if (found.size() > at_most) found.resize(at_most);
    return found;
}

/// The step on the grid of `spacing` within `radius` of `centre` that scores highest by `score`
/// (the centre on ties).
template <class Score>
Eigen::Vector2f refine_step(const Eigen::Vector2f& centre, float radius, float spacing,
                            const Score& score) {
    const int cells = static_cast<int>(std::floor(radius / spacing + 1e-4f));
    Eigen::Vector2f best = centre;
    float best_score = score(centre);
    for (int i = -cells; i <= cells; ++i) {
        for (int j = -cells; j <= cells; ++j) {
            if (i == 0 && j == 0) continue;
            const Eigen::Vector2f step =
                centre + Eigen::Vector2f(static_cast<float>(i), static_cast<float>(j)) * spacing;
            const float value = score(step);
            if (value > best_score) {
                best_score = value;
                best = step;
            }
        }
    }
    return best;
}

void check(const MovingObjectConfig& c) {
    const auto positive = [](float v, const char* key) {
        if (!(v > 0.0f)) {
            throw ConfigError(std::string("dynamic.motion_") + key + " must be positive (got " +
                              std::to_string(v) + ")");
        }
    };
    positive(c.match_m, "match_m");
    positive(c.max_step_m, "max_step_m");
    positive(c.search_m, "search_m");
    const auto share = [](float v, const char* key) {
        if (!(v >= 0.0f && v <= 1.0f)) {
            throw ConfigError(std::string("dynamic.motion_") + key + " must be in [0, 1] (got " +
                              std::to_string(v) + ")");
        }
    };
    share(c.min_match_share, "min_match_share");
    share(c.min_gain, "min_gain");
    share(c.min_scan_share, "min_scan_share");
    share(c.max_still_share, "max_still_share");
    share(c.link_share, "link_share");
    if (!(c.min_step_m >= 0.0f)) throw ConfigError("dynamic.motion_min_step_m must be >= 0");
    if (!(c.voxel_height_m >= 0.0f)) {
        throw ConfigError("dynamic.motion_voxel_height_m must be >= 0");
    }
    if (c.min_points < 1) throw ConfigError("dynamic.motion_min_points must be at least 1");
    if (c.window_scans < 1) throw ConfigError("dynamic.motion_window_scans must be at least 1");
    if (c.min_window_scans < 1) {
        throw ConfigError("dynamic.motion_min_window_scans must be at least 1");
    }
    if (c.max_gap_scans < 1) throw ConfigError("dynamic.motion_max_gap_scans must be at least 1");
}

/// Scans processed at once (their margins aside).
constexpr std::size_t kChunkScans = 64;

/// The segmentation the test uses: `objects` with the test's min_points and voxel height.
DynamicObjectConfig segmentation_of(const DynamicObjectConfig& objects,
                                    const MovingObjectConfig& config) {
    DynamicObjectConfig segmentation = objects;
    segmentation.min_points = config.min_points;
    segmentation.voxel_height_m = config.voxel_height_m;
    return segmentation;
}

/// An object's velocity (metres a scan), if the window found one.
struct Velocity {
    Eigen::Vector2f step = Eigen::Vector2f::Zero();
    bool moving = false;
};

/// Points of an object the velocity test uses (evenly thinned).
constexpr std::size_t kSearchPoints = 64;

/// The velocity of an object of scan s (its points `sample`), from the cells of the scans
/// s + k (table_at(k), null where there is none) for k up to window_scans away, or on the side
/// before it only (`past_only`). The candidates are its best steps towards the next scan and
/// from the scan before (where the object, unshifted, matches at most 1 - min_gain of its
/// points); a candidate is refined on the window's scans and is the object's velocity when the
/// object, moved at it, matches at least min_scan_share of the window's scans and, left in
/// place, at most max_still_share of them (which is tested first, for every candidate alike).
template <class TableAt>
Velocity object_velocity(const std::vector<Eigen::Vector3f>& sample, const TableAt& table_at,
                         bool past_only, const MovingObjectConfig& config) {
    constexpr std::size_t kCandidates = 4;  // per neighbouring scan
    const auto window = static_cast<std::ptrdiff_t>(config.window_scans);
    const std::ptrdiff_t last = past_only ? -1 : window;
    // The window's scans, and those of them that hold the object in place: neither depends on
    // the velocity, so an object that too few scans see, or too many hold in place, moves at no
    // velocity, and its candidates need not be searched.
    int seen = 0, still = 0;
    for (std::ptrdiff_t k = -window; k <= last; ++k) {
        const CellTable* table = k == 0 ? nullptr : table_at(k);
        if (table == nullptr) continue;
        ++seen;
        still += match_share(sample, Eigen::Vector2f::Zero(), *table) >= config.min_match_share;
    }
    if (seen < config.min_window_scans ||
        static_cast<float>(still) > config.max_still_share * static_cast<float>(seen)) {
        return Velocity{};
    }
    std::vector<Eigen::Vector2f> candidates;
    for (int dir : {1, -1}) {
        if (past_only && dir > 0) continue;
        const CellTable* table = table_at(dir);
        if (table == nullptr) continue;
        if (match_share(sample, Eigen::Vector2f::Zero(), *table) > 1.0f - config.min_gain) {
            continue;  // it is where it was
        }
        for (const StepMatch& coarse :
             good_steps(sample, *table, 2.0f * config.search_m, kCandidates, config)) {
            const Eigen::Vector2f fine = refine_step(
                coarse.step, config.search_m, config.search_m,
                [&](const Eigen::Vector2f& step) { return match_share(sample, step, *table); });
            const Eigen::Vector2f v = static_cast<float>(dir) * fine;
            if (std::none_of(candidates.begin(), candidates.end(), [&](const auto& c) {
                    return (c - v).norm() < 0.5f * config.search_m;
                })) {
                candidates.push_back(v);
            }
        }
    }
    // The summed share of the scans up to `reach` away that match at velocity v.
    const auto window_share = [&](const Eigen::Vector2f& v, std::ptrdiff_t reach) {
        float sum = 0.0f;
        for (std::ptrdiff_t k = -reach; k <= std::min(reach, last); ++k) {
            const CellTable* table = k == 0 ? nullptr : table_at(k);
            if (table != nullptr) sum += match_share(sample, static_cast<float>(k) * v, *table);
        }
        return sum;
    };
    Velocity result;
    int best_matched = -1;
    for (const Eigen::Vector2f& candidate : candidates) {
        // Off by up to half the search grid, a velocity misses the scans a few away: refined on
        // the two scans either side first, then on the whole window.
        Eigen::Vector2f v =
            refine_step(candidate, 0.6f * config.search_m, 0.2f * config.search_m,
                        [&](const Eigen::Vector2f& u) { return window_share(u, 2); });
        v = refine_step(v, 0.2f * config.search_m, 0.1f * config.search_m,
                        [&](const Eigen::Vector2f& u) { return window_share(u, window); });
        if (v.norm() < config.min_step_m) continue;
        int matched = 0;
        for (std::ptrdiff_t k = -window; k <= last; ++k) {
            const CellTable* table = k == 0 ? nullptr : table_at(k);
            if (table == nullptr) continue;
            matched +=
                match_share(sample, static_cast<float>(k) * v, *table) >= config.min_match_share;
        }
        // seen and still passed above.
        const bool moves =
            static_cast<float>(matched) >= config.min_scan_share * static_cast<float>(seen);
        if (moves && matched > best_matched) {
            best_matched = matched;
            result = {v, true};
        }
    }
    return result;
}

/// find_moving_points over all of `scans_map`, counting in `stats` the scans [core_begin,
/// core_end) only.
std::vector<std::vector<std::uint8_t>> moving_points_of(
    const std::vector<const std::vector<Eigen::Vector3f>*>& scans_map,
    const DynamicObjectConfig& objects, const MovingObjectConfig& config, std::size_t core_begin,
    std::size_t core_end, MovingObjectStats& local) {
    const std::size_t n = scans_map.size();
    std::vector<std::vector<std::uint8_t>> moving(n);
    for (std::size_t s = 0; s < n; ++s) moving[s].assign(scans_map[s]->size(), 0);
    if (n < 2) return moving;
    const DynamicObjectConfig segmentation = segmentation_of(objects, config);
    std::vector<std::unique_ptr<TrackScan>> scans(n);
    tbb::parallel_for(std::size_t(0), n, [&](std::size_t s) {
        scans[s] = std::make_unique<TrackScan>(
            *scans_map[s], find_scan_objects(*scans_map[s], segmentation), config.match_m);
    });
    const auto in_range = [n](std::ptrdiff_t t) {
        return t >= 0 && t < static_cast<std::ptrdiff_t>(n);
    };
    // 1. Each object's velocity (object_velocity), from the scans on both sides.
    std::vector<std::vector<Velocity>> velocity(n);
    tbb::parallel_for(std::size_t(0), n, [&](std::size_t s) {
        const TrackScan& scan = *scans[s];
        const auto at = static_cast<std::ptrdiff_t>(s);
        const auto table_at = [&](std::ptrdiff_t k) -> const CellTable* {
            return in_range(at + k) ? &scans[static_cast<std::size_t>(at + k)]->table : nullptr;
        };
        velocity[s].assign(scan.objects.num_objects, Velocity{});
        for (std::uint32_t o = 0; o < scan.objects.num_objects; ++o) {
            velocity[s][o] = object_velocity(scan.points_of(*scans_map[s], o, kSearchPoints),
                                             table_at, false, config);
        }
    });

    // 2. From each moving object, both ways in time at its velocity: an object of a scan up to
    // max_gap_scans away that lies where the moving one is predicted (at least link_share of its
    // points land on it when moved back) and that the scans beside it do not hold in place
    // moves too, at the same velocity, and so on.
    std::vector<std::uint32_t> first_node(n + 1, 0);
    for (std::size_t s = 0; s < n; ++s) {
        first_node[s + 1] = first_node[s] + scans[s]->objects.num_objects;
    }
    struct Reach {
        std::size_t scan;
        std::uint32_t object;
        int dir;
        Eigen::Vector2f step;  ///< towards scan + dir
    };
    std::deque<Reach> queue;
    std::vector<std::uint8_t> is_moving(first_node[n], 0);
    std::array<std::vector<std::uint8_t>, 2> reached{std::vector<std::uint8_t>(first_node[n], 0),
                                                     std::vector<std::uint8_t>(first_node[n], 0)};
    for (std::size_t s = 0; s < n; ++s) {
        const bool core = s >= core_begin && s < core_end;
        if (core) local.objects += scans[s]->objects.num_objects;
        for (std::uint32_t o = 0; o < scans[s]->objects.num_objects; ++o) {
            if (!velocity[s][o].moving) continue;
            local.moved += core;
            is_moving[first_node[s] + o] = 1;
            for (int dir : {-1, 1}) {
                reached[dir > 0][first_node[s] + o] = 1;
                queue.push_back({s, o, dir, static_cast<float>(dir) * velocity[s][o].step});
            }
        }
    }
    const float grow = 2.0f * config.match_m;
    while (!queue.empty()) {
        const Reach from = queue.front();
        queue.pop_front();
        const TrackScan& source = *scans[from.scan];
        for (int gap = 1; gap <= config.max_gap_scans; ++gap) {
            const std::ptrdiff_t t = static_cast<std::ptrdiff_t>(from.scan) + from.dir * gap;
            if (!in_range(t)) break;
            const TrackScan& target = *scans[static_cast<std::size_t>(t)];
            const Eigen::Vector2f shift = static_cast<float>(gap) * from.step;
            const Eigen::Vector3f shift3(shift.x(), shift.y(), 0.0f);
            const Eigen::Vector3f lo =
                source.lo[from.object] + shift3 - Eigen::Vector3f::Constant(grow);
            const Eigen::Vector3f hi =
                source.hi[from.object] + shift3 + Eigen::Vector3f::Constant(grow);
            bool found = false;
            for (std::uint32_t b = 0; b < target.objects.num_objects; ++b) {
                if ((target.lo[b].array() > hi.array()).any() ||
                    (target.hi[b].array() < lo.array()).any()) {
                    continue;
                }
                const std::vector<Eigen::Vector3f> points =
                    target.points_of(*scans_map[static_cast<std::size_t>(t)], b, 0);
                if (match_share(points, -shift, source.table, from.object) < config.link_share) {
                    continue;
                }
                // A static object the prediction runs into: the scans beside it hold it in place.
                bool still = false;
                for (int side : {-1, 1}) {
                    if (!in_range(t + side)) continue;
                    still = still || match_share(points, Eigen::Vector2f::Zero(),
                                                 scans[static_cast<std::size_t>(t + side)]->table) >
                                         1.0f - config.min_gain;
                }
                if (still) continue;
                found = true;
                const std::uint32_t node = first_node[static_cast<std::size_t>(t)] + b;
                if (reached[from.dir > 0][node]) continue;
                reached[from.dir > 0][node] = 1;
                is_moving[node] = 1;
                queue.push_back({static_cast<std::size_t>(t), b, from.dir, from.step});
            }
            if (found) break;
        }
    }
    for (std::size_t s = 0; s < n; ++s) {
        const TrackScan& scan = *scans[s];
        const bool core = s >= core_begin && s < core_end;
        for (std::uint32_t o = 0; o < scan.objects.num_objects; ++o) {
            if (!is_moving[first_node[s] + o]) continue;
            local.moving_objects += core;
            for (std::uint32_t j = scan.begin[o]; j < scan.begin[o + 1]; ++j) {
                moving[s][scan.order[j]] = 1;
                local.points += core;
            }
        }
    }
    return moving;
}

}  // namespace

std::vector<std::vector<std::uint8_t>> find_moving_points(
    const std::vector<const std::vector<Eigen::Vector3f>*>& scans_map,
    const DynamicObjectConfig& objects, const MovingObjectConfig& config,
    MovingObjectStats* stats) {
    check(config);
    const std::size_t n = scans_map.size();
    std::vector<std::vector<std::uint8_t>> moving(n);
    for (std::size_t s = 0; s < n; ++s) {
        if (scans_map[s] == nullptr) {
            throw DataError("moving objects: scan " + std::to_string(s) + " is missing");
        }
        moving[s].assign(scans_map[s]->size(), 0);
    }
    MovingObjectStats local;
    if (config.enabled) {
        // Chunks of scans with a margin on either side, so that the cells of a long sequence
        // are never all held at once (about 1.5 MB a scan of 13 k points): a chunk's scans see
        // the scans of the margin as they would in one run over all; only a reach longer than
        // the margin ends sooner.
        const std::size_t margin = 2 * static_cast<std::size_t>(config.window_scans) +
                                   static_cast<std::size_t>(config.max_gap_scans);
        for (std::size_t begin = 0; begin < n; begin += kChunkScans) {
            const std::size_t end = std::min(n, begin + kChunkScans);
            const std::size_t lo = begin > margin ? begin - margin : 0;
            const std::size_t hi = std::min(n, end + margin);
            const std::vector<const std::vector<Eigen::Vector3f>*> chunk(
                scans_map.begin() + static_cast<std::ptrdiff_t>(lo),
                scans_map.begin() + static_cast<std::ptrdiff_t>(hi));
            std::vector<std::vector<std::uint8_t>> flags =
                moving_points_of(chunk, objects, config, begin - lo, end - lo, local);
            for (std::size_t s = begin; s < end; ++s) moving[s] = std::move(flags[s - lo]);
        }
    }
    if (stats != nullptr) *stats = local;
    return moving;
}

struct PastMotion::State {
    DynamicObjectConfig segmentation;
    MovingObjectConfig config;
    /// The last window_scans scans' points and objects, the newest last.
    std::deque<std::pair<std::vector<Eigen::Vector3f>, std::unique_ptr<TrackScan>>> past;
};

PastMotion::PastMotion(const DynamicObjectConfig& objects, const MovingObjectConfig& config)
    : state_(std::make_unique<State>()) {
    check(config);
    state_->segmentation = segmentation_of(objects, config);
    state_->config = config;
}

PastMotion::~PastMotion() = default;
PastMotion::PastMotion(PastMotion&&) noexcept = default;
PastMotion& PastMotion::operator=(PastMotion&&) noexcept = default;

std::vector<std::uint8_t> PastMotion::add_scan(const std::vector<Eigen::Vector3f>& points_map,
                                               MovingObjectStats* stats) {
    State& state = *state_;
    const MovingObjectConfig& config = state.config;
    std::vector<std::uint8_t> moving(points_map.size(), 0);
    MovingObjectStats local;
    if (!config.enabled) {
        if (stats != nullptr) *stats = local;
        return moving;
    }
    auto scan = std::make_unique<TrackScan>(
        points_map, find_scan_objects(points_map, state.segmentation), config.match_m);
    const std::size_t n = state.past.size();
    const auto table_at = [&](std::ptrdiff_t k) -> const CellTable* {
        const std::ptrdiff_t index = static_cast<std::ptrdiff_t>(n) + k;  // k < 0
        return k < 0 && index >= 0 ? &state.past[static_cast<std::size_t>(index)].second->table
                                   : nullptr;
    };
    std::vector<Velocity> velocity(scan->objects.num_objects);
    tbb::parallel_for(std::uint32_t(0), scan->objects.num_objects, [&](std::uint32_t o) {
        velocity[o] =
            object_velocity(scan->points_of(points_map, o, kSearchPoints), table_at, true, config);
    });
    local.objects = scan->objects.num_objects;
    for (std::uint32_t o = 0; o < scan->objects.num_objects; ++o) {
        if (!velocity[o].moving) continue;
        ++local.moved;
        ++local.moving_objects;
        for (std::uint32_t j = scan->begin[o]; j < scan->begin[o + 1]; ++j) {
            moving[scan->order[j]] = 1;
            ++local.points;
        }
    }
    state.past.emplace_back(points_map, std::move(scan));
    while (state.past.size() > static_cast<std::size_t>(config.window_scans)) {
        state.past.pop_front();
    }
    if (stats != nullptr) *stats = local;
    return moving;
}

void PastMotion::clear() { state_->past.clear(); }

}  // namespace shine
