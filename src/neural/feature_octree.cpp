#include "shine/map/feature_octree.hpp"

#include <algorithm>
#include <cmath>
#include <random>

#include "shine/core/error.hpp"
#include "shine/map/feature_octree_impl.hpp"

namespace shine {
namespace {

// The 8 corner offsets of a cell, bit 0 = x, bit 1 = y, bit 2 = z.
constexpr int kCornerOffset[8][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {1, 1, 0},
                                     {0, 0, 1}, {1, 0, 1}, {0, 1, 1}, {1, 1, 1}};

std::uint64_t mix64(std::uint64_t x) {
    // splitmix64 finaliser: a well-spread hash of the corner's identity.
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

template <typename AccessorT>
bool lookup_cell(AccessorT& accessor, double cell_size_m, const Eigen::Vector3f& p,
                 LevelCorners& out) {
    const double inv = 1.0 / cell_size_m;
    const double gx = p.x() * inv, gy = p.y() * inv, gz = p.z() * inv;
    const double fx = std::floor(gx), fy = std::floor(gy), fz = std::floor(gz);
    out.t[0] = static_cast<float>(gx - fx);
    out.t[1] = static_cast<float>(gy - fy);
    out.t[2] = static_cast<float>(gz - fz);
    const openvdb::Coord base(static_cast<int>(fx), static_cast<int>(fy), static_cast<int>(fz));
    for (int c = 0; c < 8; ++c) {
        const openvdb::Coord corner =
            base.offsetBy(kCornerOffset[c][0], kCornerOffset[c][1], kCornerOffset[c][2]);
        const std::int32_t row = accessor.getValue(corner);
        if (row < 0) return false;
        out.rows[c] = row;
    }
    return true;
}

}  // namespace

void FeatureOctree::initial_feature(std::uint64_t seed, int level, const Eigen::Vector3i& corner,
                                    float init_std, float* out, int feature_dim) {
    std::uint64_t h = mix64(seed);
    h = mix64(h ^ static_cast<std::uint64_t>(level));
    h = mix64(h ^ static_cast<std::uint32_t>(corner.x()));
    h = mix64(h ^ static_cast<std::uint32_t>(corner.y()));
    h = mix64(h ^ static_cast<std::uint32_t>(corner.z()));
    std::mt19937_64 rng(h);
    std::normal_distribution<float> normal(0.0f, init_std);
    for (int i = 0; i < feature_dim; ++i) out[i] = normal(rng);
}

FeatureOctree::FeatureOctree(const FeatureOctreeConfig& config)
    : config_(config), impl_(std::make_unique<FeatureOctreeImpl>()) {
    if (!(config.leaf_size_m > 0.0) || !std::isfinite(config.leaf_size_m)) {
        throw ConfigError("leaf_size_m must be a positive number of metres, got " +
                          std::to_string(config.leaf_size_m));
    }
    if (config.num_levels < 1 || config.num_levels > 8) {
        throw ConfigError("num_levels must be between 1 and 8, got " +
                          std::to_string(config.num_levels));
    }
    if (config.feature_dim < 1 || config.feature_dim > 64) {
        throw ConfigError("feature_dim must be between 1 and 64, got " +
                          std::to_string(config.feature_dim));
    }
    openvdb::initialize();
    for (int level = 0; level < config.num_levels; ++level) {
        auto grid = openvdb::Int32Grid::create(-1);
        grid->setName("feature_level_" + std::to_string(level));
        grid->setTransform(openvdb::math::Transform::createLinearTransform(cell_size_m(level)));
        grid->setGridClass(openvdb::GRID_UNKNOWN);
        impl_->level_grids.push_back(grid);
    }
}

FeatureOctree::~FeatureOctree() = default;
FeatureOctree::FeatureOctree(FeatureOctree&&) noexcept = default;
FeatureOctree& FeatureOctree::operator=(FeatureOctree&&) noexcept = default;

double FeatureOctree::cell_size_m(int level) const {
    return config_.leaf_size_m * static_cast<double>(1 << level);
}

std::size_t FeatureOctree::allocate_cells(const std::vector<Eigen::Vector3f>& points_map) {
    const int dim = config_.feature_dim;
    std::size_t added = 0;
    for (int level = 0; level < config_.num_levels; ++level) {
        // Collect the distinct cells first so that each corner is visited once per cell.
        const double inv = 1.0 / cell_size_m(level);
        const double margin_m = config_.allocation_margin_ratio * config_.leaf_size_m;
        std::vector<Eigen::Vector3i> cells;
        cells.reserve(points_map.size() * 2);
        for (const auto& p : points_map) {
            int lo[3], hi[3];
            for (int a = 0; a < 3; ++a) {
                lo[a] = static_cast<int>(std::floor((p[a] - margin_m) * inv));
                hi[a] = static_cast<int>(std::floor((p[a] + margin_m) * inv));
            }
            for (int x = lo[0]; x <= hi[0]; ++x) {
                for (int y = lo[1]; y <= hi[1]; ++y) {
                    for (int z = lo[2]; z <= hi[2]; ++z) cells.emplace_back(x, y, z);
                }
            }
        }
        std::sort(
            cells.begin(), cells.end(), [](const Eigen::Vector3i& a, const Eigen::Vector3i& b) {
                return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
            });
        cells.erase(std::unique(cells.begin(), cells.end()), cells.end());

        auto accessor = impl_->level_grids[level]->getAccessor();
        for (const auto& cell : cells) {
            for (const auto& offset : kCornerOffset) {
                const openvdb::Coord corner(cell.x() + offset[0], cell.y() + offset[1],
                                            cell.z() + offset[2]);
                if (accessor.getValue(corner) >= 0) continue;
                const std::size_t row = features_.size() / dim;
                if (row >= static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
                    throw Error("feature map exceeds 2^31 corners; use a larger leaf size");
                }
                accessor.setValue(corner, static_cast<std::int32_t>(row));
                features_.resize(features_.size() + dim);
                initial_feature(config_.seed, level,
                                Eigen::Vector3i(corner.x(), corner.y(), corner.z()),
                                config_.init_std, features_.data() + row * dim, dim);
                ++added;
            }
        }
    }
    return added;
}

bool FeatureOctree::find_cell(int level, const Eigen::Vector3f& point_map,
                              LevelCorners& out) const {
    auto accessor = impl_->level_grids[level]->getConstUnsafeAccessor();
    return lookup_cell(accessor, cell_size_m(level), point_map, out);
}

bool FeatureOctree::has_leaf_cell(const Eigen::Vector3i& cell) const {
    auto accessor = impl_->level_grids[0]->getConstUnsafeAccessor();
    for (const auto& offset : kCornerOffset) {
        if (accessor.getValue(openvdb::Coord(cell.x() + offset[0], cell.y() + offset[1],
                                             cell.z() + offset[2])) < 0) {
            return false;
        }
    }
    return true;
}

std::vector<Eigen::Vector3i> FeatureOctree::cells(int level) const {
    std::vector<Eigen::Vector3i> cells;
    const auto& grid = *impl_->level_grids.at(level);
    auto accessor = grid.getConstUnsafeAccessor();
    for (auto it = grid.cbeginValueOn(); it; ++it) {
        // Every allocated cell has its (0,0,0) corner allocated: test each corner as a cell origin.
        const openvdb::Coord c = it.getCoord();
        bool complete = true;
        for (int k = 1; k < 8 && complete; ++k) {
            complete = accessor.getValue(c.offsetBy(kCornerOffset[k][0], kCornerOffset[k][1],
                                                    kCornerOffset[k][2])) >= 0;
        }
        if (complete) cells.emplace_back(c.x(), c.y(), c.z());
    }
    std::sort(cells.begin(), cells.end(), [](const Eigen::Vector3i& a, const Eigen::Vector3i& b) {
        return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
    });
    return cells;
}

std::size_t FeatureOctree::num_corners(int level) const {
    return impl_->level_grids.at(level)->activeVoxelCount();
}

std::size_t FeatureOctree::structure_bytes() const {
    std::size_t bytes = 0;
    for (const auto& grid : impl_->level_grids) bytes += grid->memUsage();
    return bytes;
}

std::size_t FeatureOctree::memory_bytes() const { return feature_bytes() + structure_bytes(); }

struct CellLookup::Accessors {
    std::vector<openvdb::Int32Grid::ConstUnsafeAccessor> levels;
};

CellLookup::CellLookup(const FeatureOctree& octree)
    : octree_(octree), accessors_(std::make_unique<Accessors>()) {
    for (const auto& grid : octree.impl().level_grids) {
        accessors_->levels.push_back(grid->getConstUnsafeAccessor());
    }
}

CellLookup::~CellLookup() = default;

bool CellLookup::find_cell(int level, const Eigen::Vector3f& point_map, LevelCorners& out) {
    return lookup_cell(accessors_->levels[level], octree_.cell_size_m(level), point_map, out);
}

}  // namespace shine
