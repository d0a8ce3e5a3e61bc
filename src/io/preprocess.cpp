// Per-scan preprocessing: invalid points, range crop, box crop, voxel downsampling.
#include "shine/io/preprocess.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <unordered_map>

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

std::vector<Eigen::Vector3f> preprocess_scan(const std::vector<Eigen::Vector3f>& points_sensor,
                                             const PreprocessConfig& config, const fs::path& source,
                                             PreprocessStats* stats) {
    using namespace preprocess_internal;
    validate(config);
    PreprocessStats s;
    s.input = points_sensor.size();
    std::vector<Eigen::Vector3f> kept;
    kept.reserve(points_sensor.size());
    for (std::size_t i = 0; i < points_sensor.size(); ++i) {
        const Eigen::Vector3f& p = points_sensor[i];
        if (!p.allFinite()) {
            if (config.invalid_points == InvalidPointPolicy::kError) {
                char text[160];
                std::snprintf(text, sizeof(text), "point %zu is (%g, %g, %g)", i,
                              static_cast<double>(p.x()), static_cast<double>(p.y()),
                              static_cast<double>(p.z()));
                throw DataError("scan '" + source.string() + "': " + text +
                                ", not finite; set 'preprocess.invalid_points: drop' (the "
                                "default) to skip and count such points");
            }
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
        kept.push_back(p);
    }

    if (config.voxel_downsample_m > 0.0 && !kept.empty()) {
        const double v = config.voxel_downsample_m;
        // Keys must fit in int64; 2^62 voxels leave room for the +1 neighbours of later users.
        constexpr double kMaxKey = 4.6e18;
        struct Best {
            std::size_t index;
            double distance2;
        };
        std::unordered_map<VoxelKey, Best, VoxelKeyHash> voxels;
        voxels.reserve(kept.size());
        // A scan lists its points along the beams, so consecutive points often share a voxel:
        // the previous point's voxel is checked before the table (the map's values do not move).
        VoxelKey last_key{0, 0, 0};
        Best* last = nullptr;
        for (std::size_t i = 0; i < kept.size(); ++i) {
            const Eigen::Vector3d scaled = kept[i].cast<double>() / v;
            const Eigen::Vector3d cell = scaled.array().floor();
            if ((cell.array().abs() > kMaxKey).any()) {
                throw DataError("scan '" + source.string() + "': point " + std::to_string(i) +
                                " is too far away for voxel size " + std::to_string(v) +
                                " m; set a finite max_range_m");
            }
            const VoxelKey key{static_cast<std::int64_t>(cell.x()),
                               static_cast<std::int64_t>(cell.y()),
                               static_cast<std::int64_t>(cell.z())};
            // Distance to the voxel centre in voxel units (same order as in metres).
            const double d2 = (scaled - cell - Eigen::Vector3d::Constant(0.5)).squaredNorm();
            if (last == nullptr || !(key == last_key)) {
                auto [it, inserted] = voxels.try_emplace(key, Best{i, d2});
                last_key = key;
                last = &it->second;
                if (inserted) continue;
            }
            Best& best = *last;
            if (d2 < best.distance2 ||
                (d2 == best.distance2 && lexicographic_less(kept[i], kept[best.index]))) {
                best = Best{i, d2};
            }
        }
        // Output sorted by voxel key: the result is then independent of the input order, not
        // just as a set but element by element.
        std::vector<std::pair<VoxelKey, std::size_t>> chosen;
        chosen.reserve(voxels.size());
        for (const auto& [key, best] : voxels) chosen.emplace_back(key, best.index);
        std::sort(chosen.begin(), chosen.end(),
                  [](const auto& a, const auto& b) { return a.first < b.first; });
        std::vector<Eigen::Vector3f> downsampled;
        downsampled.reserve(chosen.size());
        for (const auto& c : chosen) downsampled.push_back(kept[c.second]);
        s.dropped_downsample = kept.size() - downsampled.size();
        kept = std::move(downsampled);
    }
    s.output = kept.size();
    if (stats != nullptr) *stats = s;
    return kept;
}

}  // namespace shine
