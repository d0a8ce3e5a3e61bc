// Per-scan preprocessing: invalid points, range crop, box crop, voxel downsampling.
#include "shine/io/preprocess.hpp"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <unordered_map>
#include <utility>

#include "shine/core/error.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace preprocess_internal {
namespace {

struct VoxelKey {
    std::int64_t x, y, z;
    bool operator==(const VoxelKey& o) const { return x == o.x && y == o.y && z == o.z; }
    bool operator<(const VoxelKey& o) const {
        return x != o.x ? x < o.x : (y != o.y ? y < o.y : z < o.z);
    }
};

struct VoxelKeyHash {
    std::size_t operator()(const VoxelKey& k) const {
        // Large odd multipliers spread neighbouring voxels over the table.
        const std::uint64_t h = static_cast<std::uint64_t>(k.x) * 0x9E3779B97F4A7C15ull ^
                                static_cast<std::uint64_t>(k.y) * 0xC2B2AE3D27D4EB4Full ^
                                static_cast<std::uint64_t>(k.z) * 0x165667B19E3779F9ull;
        return static_cast<std::size_t>(h ^ (h >> 32));
    }
};

/// Total order on points used to break exact distance ties, so the kept point never depends on
/// the input order.
bool lexicographic_less(const Eigen::Vector3f& a, const Eigen::Vector3f& b) {
    return a.x() != b.x() ? a.x() < b.x() : (a.y() != b.y() ? a.y() < b.y() : a.z() < b.z());
}

void validate(const PreprocessConfig& c) {
    const auto bad = [](const std::string& key, double value, const std::string& rule) {
        char text[64];
        std::snprintf(text, sizeof(text), "%g", value);
        throw ConfigError("preprocess." + key + " = " + text + ": " + rule);
    };
    if (!(c.min_range_m >= 0.0) || std::isinf(c.min_range_m)) {
        bad("min_range_m", c.min_range_m, "must be a finite value >= 0");
    }
    if (!(c.max_range_m > c.min_range_m)) {
        bad("max_range_m", c.max_range_m, "must be greater than min_range_m");
    }
    if (!(c.voxel_downsample_m >= 0.0) || std::isinf(c.voxel_downsample_m)) {
        bad("voxel_downsample_m", c.voxel_downsample_m, "must be a finite value >= 0 (0 disables)");
    }
    for (int k = 0; k < 3; ++k) {
        if (std::isnan(c.box_min_sensor_m[k]) || std::isnan(c.box_max_sensor_m[k]) ||
            c.box_min_sensor_m[k] > c.box_max_sensor_m[k]) {
            bad(std::string("box_min_sensor_m/box_max_sensor_m[") + static_cast<char>('0' + k) +
                    "]",
                c.box_min_sensor_m[k], "box minimum must not exceed the maximum");
        }
    }
}

}  // namespace
}  // namespace preprocess_internal

PreprocessStats& PreprocessStats::operator+=(const PreprocessStats& other) {
    input += other.input;
    dropped_nonfinite += other.dropped_nonfinite;
    dropped_zero_range += other.dropped_zero_range;
    dropped_range += other.dropped_range;
    dropped_box += other.dropped_box;
    dropped_downsample += other.dropped_downsample;
    output += other.output;
    return *this;
}

namespace {

constexpr std::size_t kNone = static_cast<std::size_t>(-1);
/// Input points per block of the parallel passes.
constexpr std::size_t kBlockPoints = 16384;
/// Voxels are split by key hash into this many sets, thinned in parallel.
constexpr std::size_t kVoxelParts = 4;

/// A kept point and, when downsampling, its voxel and its squared distance to the voxel centre
/// (in voxel units).
struct Candidate {
    preprocess_internal::VoxelKey key;
    double distance2;
    Eigen::Vector3f point;
    std::uint32_t index;  ///< in the input
};

/// One block of the input: its kept points (grouped by voxel part when downsampling), its counts,
/// and the first point (block-local index) that stops the scan, if any.
struct Block {
    std::vector<Eigen::Vector3f> kept;               ///< without downsampling
    std::vector<std::uint32_t> kept_index;           ///< their input indices
    std::vector<Candidate> candidates[kVoxelParts];  ///< with downsampling
    PreprocessStats stats;
    std::size_t first_nonfinite = kNone;  ///< input index
    std::size_t first_too_far = kNone;    ///< index among the block's kept points
    std::size_t kept_count = 0;
};

}  // namespace

std::vector<Eigen::Vector3f> preprocess_scan(const std::vector<Eigen::Vector3f>& points_sensor,
                                             const PreprocessConfig& config, const fs::path& source,
                                             PreprocessStats* stats) {
    return preprocess_scan(points_sensor, config, source, stats, nullptr);
}

std::vector<Eigen::Vector3f> preprocess_scan(const std::vector<Eigen::Vector3f>& points_sensor,
                                             const PreprocessConfig& config, const fs::path& source,
                                             PreprocessStats* stats,
                                             std::vector<std::uint32_t>* voxel_begin,
                                             std::vector<std::uint32_t>* source_index) {
    using namespace preprocess_internal;
    validate(config);
    if (voxel_begin != nullptr) voxel_begin->clear();
    if (source_index != nullptr) source_index->clear();
    const bool downsample = config.voxel_downsample_m > 0.0;
    const bool grouped =
        downsample && voxel_begin != nullptr && config.voxel_points == VoxelPoints::kAll;
    const double v = config.voxel_downsample_m;
    // Keys must fit in int64; 2^62 voxels leave room for the +1 neighbours of later users.
    constexpr double kMaxKey = 4.6e18;
    const VoxelKeyHash hash;

    // 1. Filter, and with downsampling find each point's voxel, in blocks in parallel.
    const std::size_t num_blocks = (points_sensor.size() + kBlockPoints - 1) / kBlockPoints;
    std::vector<Block> blocks(num_blocks);
    tbb::parallel_for(std::size_t(0), num_blocks, [&](std::size_t b) {
        Block& block = blocks[b];
        PreprocessStats& s = block.stats;
        const std::size_t end = std::min(points_sensor.size(), (b + 1) * kBlockPoints);
        for (std::size_t i = b * kBlockPoints; i < end; ++i) {
            const Eigen::Vector3f& p = points_sensor[i];
            if (!p.allFinite()) {
                if (block.first_nonfinite == kNone) block.first_nonfinite = i;
                ++s.dropped_nonfinite;
                continue;
            }
            const Eigen::Vector3d pd = p.cast<double>();
            const double range_m = pd.norm();
            if (range_m == 0.0) {
                ++s.dropped_zero_range;
                continue;
            }
            if (range_m < config.min_range_m || range_m > config.max_range_m) {
                ++s.dropped_range;
                continue;
            }
            if ((pd.array() < config.box_min_sensor_m.array()).any() ||
                (pd.array() > config.box_max_sensor_m.array()).any()) {
                ++s.dropped_box;
                continue;
            }
            const std::size_t local = block.kept_count++;
            if (!downsample) {
                block.kept.push_back(p);
                if (source_index != nullptr)
                    block.kept_index.push_back(static_cast<std::uint32_t>(i));
                continue;
            }
            const Eigen::Vector3d scaled = pd / v;
            const Eigen::Vector3d cell = scaled.array().floor();
            if ((cell.array().abs() > kMaxKey).any()) {
                if (block.first_too_far == kNone) block.first_too_far = local;
                continue;
            }
            const VoxelKey key{static_cast<std::int64_t>(cell.x()),
                               static_cast<std::int64_t>(cell.y()),
                               static_cast<std::int64_t>(cell.z())};
            // Distance to the voxel centre in voxel units (same order as in metres).
            const double d2 = (scaled - cell - Eigen::Vector3d::Constant(0.5)).squaredNorm();
            block.candidates[hash(key) % kVoxelParts].push_back(
                {key, d2, p, static_cast<std::uint32_t>(i)});
        }
    });

    PreprocessStats s;
    s.input = points_sensor.size();
    for (const Block& block : blocks) {
        if (block.first_nonfinite != kNone && config.invalid_points == InvalidPointPolicy::kError) {
            const Eigen::Vector3f& p = points_sensor[block.first_nonfinite];
            char text[160];
            std::snprintf(text, sizeof(text), "point %zu is (%g, %g, %g)", block.first_nonfinite,
                          static_cast<double>(p.x()), static_cast<double>(p.y()),
                          static_cast<double>(p.z()));
            throw DataError("scan '" + source.string() + "': " + text +
                            ", not finite; set 'preprocess.invalid_points: drop' (the "
                            "default) to skip and count such points");
        }
        s += block.stats;  // a block counts only its drops
    }
    std::size_t kept_before = 0;  // the error names the point's index among the kept points
    for (const Block& block : blocks) {
        if (block.first_too_far != kNone) {
            throw DataError("scan '" + source.string() + "': point " +
                            std::to_string(kept_before + block.first_too_far) +
                            " is too far away for voxel size " + std::to_string(v) +
                            " m; set a finite max_range_m");
        }
        kept_before += block.kept_count;
    }
    const std::size_t kept_count = kept_before;

    std::vector<Eigen::Vector3f> kept;
    if (!downsample) {
        kept.reserve(kept_count);
        for (const Block& block : blocks) {
            kept.insert(kept.end(), block.kept.begin(), block.kept.end());
            if (source_index != nullptr) {
                source_index->insert(source_index->end(), block.kept_index.begin(),
                                     block.kept_index.end());
            }
        }
    } else if (grouped && kept_count > 0) {
        // 2'. Every point, grouped by voxel: sorted by key, then as the thinning ranks them (a
        // total order, so the result does not depend on the input order either).
        std::vector<const Candidate*> all;
        all.reserve(kept_count);
        for (const Block& block : blocks) {
            for (const auto& part : block.candidates) {
                for (const Candidate& c : part) all.push_back(&c);
            }
        }
        std::sort(all.begin(), all.end(), [](const Candidate* a, const Candidate* b) {
            if (!(a->key == b->key)) return a->key < b->key;
            if (a->distance2 != b->distance2) return a->distance2 < b->distance2;
            return lexicographic_less(a->point, b->point);
        });
        kept.reserve(all.size());
        for (std::size_t i = 0; i < all.size(); ++i) {
            if (i == 0 || !(all[i]->key == all[i - 1]->key)) {
                voxel_begin->push_back(static_cast<std::uint32_t>(i));
            }
            kept.push_back(all[i]->point);
            if (source_index != nullptr) source_index->push_back(all[i]->index);
        }
    } else if (kept_count > 0) {
        // 2. Per voxel, the point closest to its centre (exact ties: the lexicographically
        // smaller point), a total order, so neither the input order nor the split into blocks and
        // parts changes the choice. Each part of the voxels is thinned in parallel, visiting its
        // points in input order.
        std::vector<std::pair<VoxelKey, const Candidate*>> chosen[kVoxelParts];
        tbb::parallel_for(std::size_t(0), kVoxelParts, [&](std::size_t part) {
            // Per voxel, its best candidate so far.
            std::unordered_map<VoxelKey, const Candidate*, VoxelKeyHash> voxels;
            std::size_t count = 0;
            for (const Block& block : blocks) count += block.candidates[part].size();
            voxels.reserve(count);
            // A scan lists its points along the beams, so consecutive points often share a voxel:
            // the previous point's voxel is checked before the table (the map's values do not
            // move).
            const VoxelKey* last_key = nullptr;
            const Candidate** last = nullptr;
            for (const Block& block : blocks) {
                for (const Candidate& c : block.candidates[part]) {
                    if (last == nullptr || !(c.key == *last_key)) {
                        auto [it, inserted] = voxels.try_emplace(c.key, &c);
                        last_key = &it->first;
                        last = &it->second;
                        if (inserted) continue;
                    }
                    const Candidate& best = **last;
                    if (c.distance2 < best.distance2 || (c.distance2 == best.distance2 &&
                                                         lexicographic_less(c.point, best.point))) {
                        *last = &c;
                    }
                }
            }
            chosen[part].reserve(voxels.size());
            for (const auto& [key, best] : voxels) chosen[part].emplace_back(key, best);
        });
        // Output sorted by voxel key: the result is then independent of the input order, not
        // just as a set but element by element.
        std::vector<std::pair<VoxelKey, const Candidate*>> all;
        std::size_t voxels = 0;
        for (const auto& part : chosen) voxels += part.size();
        all.reserve(voxels);
        for (const auto& part : chosen) all.insert(all.end(), part.begin(), part.end());
        std::sort(all.begin(), all.end(),
                  [](const auto& a, const auto& b) { return a.first < b.first; });
        kept.reserve(all.size());
        for (const auto& c : all) {
            kept.push_back(c.second->point);
            if (source_index != nullptr) source_index->push_back(c.second->index);
        }
        s.dropped_downsample = kept_count - kept.size();
    }
    s.output = kept.size();
    if (stats != nullptr) *stats = s;
    return kept;
}

}  // namespace shine
