// Dynamic objects: the votes of part of a compact object speak for all of it.
#include "shine/sampling/dynamic_objects.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <string>
#include <unordered_map>

#include "shine/core/error.hpp"

namespace shine {

namespace dynamic_objects_internal {
namespace {

constexpr std::int64_t kOffset = std::int64_t(1) << 20;
constexpr std::uint64_t kMask = (std::uint64_t(1) << 21) - 1;

/// Integer cell coordinates packed into 64 bits (21 bits each, offset to be positive).
std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
    return ((std::uint64_t(x + kOffset) & kMask) << 42) |
           ((std::uint64_t(y + kOffset) & kMask) << 21) | (std::uint64_t(z + kOffset) & kMask);
}

std::int64_t cell(float v, float size) { return std::int64_t(std::floor(v / size)); }

/// Union-find with path halving; the smaller index becomes the root, so that the result does
/// not depend on the order of the unions.
struct Components {
    std::vector<std::uint32_t> parent;
    explicit Components(std::size_t n) : parent(n) {
        std::iota(parent.begin(), parent.end(), std::uint32_t(0));
    }
    std::uint32_t find(std::uint32_t a) {
        while (parent[a] != a) {
            parent[a] = parent[parent[a]];
            a = parent[a];
        }
        return a;
    }
    void join(std::uint32_t a, std::uint32_t b) {
        a = find(a);
        b = find(b);
        if (a == b) return;
        if (a < b) {
            parent[b] = a;
        } else {
            parent[a] = b;
        }
    }
};

void check(const DynamicObjectConfig& c) {
    const auto positive = [](float v, const char* key) {
        if (!(v > 0.0f)) {
            throw ConfigError(std::string("dynamic.object_") + key + " must be positive (got " +
                              std::to_string(v) + ")");
        }
    };
    positive(c.voxel_m, "voxel_m");
    positive(c.ground_cell_m, "ground_cell_m");
    positive(c.max_extent_m, "max_extent_m");
    positive(c.max_height_m, "max_height_m");
    if (!(c.min_dynamic_share >= 0.0f && c.min_dynamic_share <= 1.0f)) {
        throw ConfigError("dynamic.object_min_dynamic_share must be in [0, 1] (got " +
                          std::to_string(c.min_dynamic_share) + ")");
    }
    if (c.min_points < 1) throw ConfigError("dynamic.object_min_points must be at least 1");
    if (c.min_dynamic_points < 1) {
        throw ConfigError("dynamic.object_min_dynamic_points must be at least 1");
    }
    if (!(c.min_height_m >= 0.0f)) {
        throw ConfigError("dynamic.object_min_height_m must be >= 0");
    }
}

}  // namespace
}  // namespace dynamic_objects_internal

ScanObjects find_scan_objects(const std::vector<Eigen::Vector3f>& points_map,
                              const DynamicObjectConfig& config) {
    using namespace dynamic_objects_internal;
    check(config);
    const std::size_t n = points_map.size();
    ScanObjects result;
    result.object_of.assign(n, ScanObjects::kNoObject);

    // 1. The lowest point of each ground cell, then each point's height above the lowest of the
    // 3 x 3 cells around it.
    std::unordered_map<std::uint64_t, float> lowest;
    lowest.reserve(n / 4);
    for (const Eigen::Vector3f& p : points_map) {
        if (!p.allFinite()) continue;
        const std::uint64_t key =
            pack(cell(p.x(), config.ground_cell_m), cell(p.y(), config.ground_cell_m), 0);
        auto [it, inserted] = lowest.emplace(key, p.z());
        if (!inserted) it->second = std::min(it->second, p.z());
    }
    // The ground height of each cell, once per cell (a scan has far fewer cells than points).
    std::unordered_map<std::uint64_t, float> ground_of_cell;
    ground_of_cell.reserve(lowest.size());
    for (const auto& [key, z] : lowest) {
        const auto gx = static_cast<std::int64_t>((key >> 42) & kMask) - kOffset;
        const auto gy = static_cast<std::int64_t>((key >> 21) & kMask) - kOffset;
        float ground = z;
        for (std::int64_t dx = -1; dx <= 1; ++dx) {
            for (std::int64_t dy = -1; dy <= 1; ++dy) {
                const auto it = lowest.find(pack(gx + dx, gy + dy, 0));
                if (it != lowest.end()) ground = std::min(ground, it->second);
            }
        }
        ground_of_cell.emplace(key, ground);
    }
    // 2. Object points in voxels, voxels joined to their touching neighbours.
    constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
    std::vector<std::uint32_t> voxel_of(n, kNone);
    std::unordered_map<std::uint64_t, std::uint32_t> voxels;
    std::vector<std::array<std::int64_t, 3>> voxel_cells;
    for (std::size_t i = 0; i < n; ++i) {
        const Eigen::Vector3f& p = points_map[i];
        if (!p.allFinite()) continue;
        const float ground = ground_of_cell.at(
            pack(cell(p.x(), config.ground_cell_m), cell(p.y(), config.ground_cell_m), 0));
        if (p.z() - ground < config.min_height_m) continue;
        const std::array<std::int64_t, 3> c = {
            cell(p.x(), config.voxel_m), cell(p.y(), config.voxel_m),
            cell(p.z(), config.voxel_height_m > 0.0f ? config.voxel_height_m : config.voxel_m)};
        auto [it, inserted] =
            voxels.emplace(pack(c[0], c[1], c[2]), static_cast<std::uint32_t>(voxel_cells.size()));
        if (inserted) voxel_cells.push_back(c);
        voxel_of[i] = it->second;
    }
    // Each touching pair once: every voxel asks the 13 of its 26 neighbours that come after it
    // (in x, then y, then z); the components do not depend on the order of the joins.
    Components components(voxel_cells.size());
    for (std::uint32_t v = 0; v < voxel_cells.size(); ++v) {
        const auto& c = voxel_cells[v];
        for (std::int64_t dx = 0; dx <= 1; ++dx) {
            for (std::int64_t dy = (dx == 0 ? 0 : -1); dy <= 1; ++dy) {
                for (std::int64_t dz = (dx == 0 && dy == 0 ? 1 : -1); dz <= 1; ++dz) {
                    const auto it = voxels.find(pack(c[0] + dx, c[1] + dy, c[2] + dz));
                    if (it != voxels.end()) components.join(v, it->second);
                }
            }
        }
    }
    // 3. Each component's size and extent; the compact ones are numbered in order of their
    // first point.
    struct Extent {
        std::size_t points = 0;
        Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity());
        Eigen::Vector3f hi = Eigen::Vector3f::Constant(-std::numeric_limits<float>::infinity());
        std::uint32_t id = kNone;  // its object, kNotCompact, or kNone before its first point
    };
    constexpr std::uint32_t kNotCompact = kNone - 1;
    std::vector<Extent> extents(voxel_cells.size());
    for (std::size_t i = 0; i < n; ++i) {
        if (voxel_of[i] == kNone) continue;
        Extent& e = extents[components.find(voxel_of[i])];
        ++e.points;
        e.lo = e.lo.cwiseMin(points_map[i]);
        e.hi = e.hi.cwiseMax(points_map[i]);
    }
    for (std::size_t i = 0; i < n; ++i) {
        if (voxel_of[i] == kNone) continue;
        Extent& e = extents[components.find(voxel_of[i])];
        if (e.id == kNone) {
            const Eigen::Vector3f size = e.hi - e.lo;
            const bool compact = e.points >= static_cast<std::size_t>(config.min_points) &&
                                 size.head<2>().norm() <= config.max_extent_m &&
                                 size.z() <= config.max_height_m;
            e.id = compact ? result.num_objects++ : kNotCompact;
        }
        if (e.id != kNotCompact) result.object_of[i] = e.id;
    }
    return result;
}

namespace {
/// True when no object can become dynamic: spreading is off or no point is dynamic.
bool nothing_to_spread(const std::vector<std::uint8_t>& dynamic,
                       const DynamicObjectConfig& config) {
    return config.min_dynamic_share <= 0.0f ||
           std::none_of(dynamic.begin(), dynamic.end(), [](std::uint8_t d) { return d != 0; });
}
}  // namespace

DynamicObjectStats spread_dynamic_to_objects(const ScanObjects& objects,
                                             std::vector<std::uint8_t>& dynamic,
                                             const DynamicObjectConfig& config) {
    using namespace dynamic_objects_internal;
    check(config);
    if (dynamic.size() != objects.object_of.size()) {
        throw DataError("dynamic objects: " + std::to_string(dynamic.size()) + " flags for " +
                        std::to_string(objects.object_of.size()) + " points");
    }
    DynamicObjectStats stats;
    if (nothing_to_spread(dynamic, config)) return stats;
    stats.objects = objects.num_objects;
    std::vector<std::size_t> points(objects.num_objects, 0), moving(objects.num_objects, 0);
    for (std::size_t i = 0; i < dynamic.size(); ++i) {
        const std::uint32_t o = objects.object_of[i];
        if (o == ScanObjects::kNoObject) continue;
        ++points[o];
        moving[o] += dynamic[i] ? 1 : 0;
    }
    std::vector<std::uint8_t> spread(objects.num_objects, 0);
    for (std::uint32_t o = 0; o < objects.num_objects; ++o) {
        spread[o] = moving[o] >= static_cast<std::size_t>(config.min_dynamic_points) &&
                    static_cast<double>(moving[o]) >=
                        static_cast<double>(config.min_dynamic_share) * points[o];
        stats.objects_dynamic += spread[o];
    }
    for (std::size_t i = 0; i < dynamic.size(); ++i) {
        const std::uint32_t o = objects.object_of[i];
        if (o == ScanObjects::kNoObject || dynamic[i] || !spread[o]) continue;
        dynamic[i] = 1;
        ++stats.points_added;
    }
    return stats;
}

DynamicObjectStats spread_dynamic_to_objects(const std::vector<Eigen::Vector3f>& points_map,
                                             std::vector<std::uint8_t>& dynamic,
                                             const DynamicObjectConfig& config) {
    dynamic_objects_internal::check(config);
    if (dynamic.size() != points_map.size()) {
        throw DataError("dynamic objects: " + std::to_string(dynamic.size()) + " flags for " +
                        std::to_string(points_map.size()) + " points");
    }
    if (nothing_to_spread(dynamic, config)) return {};  // no segmentation needed
    return spread_dynamic_to_objects(find_scan_objects(points_map, config), dynamic, config);
}

}  // namespace shine
