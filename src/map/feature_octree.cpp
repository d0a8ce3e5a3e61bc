#include "shine/map/feature_octree.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "shine/core/error.hpp"
#include "shine/core/mt19937_64_prefix.hpp"
#include "shine/map/feature_octree_impl.hpp"

namespace shine {

const char* to_string(Interpolation interpolation) {
    return interpolation == Interpolation::kLinear ? "linear" : "smoothstep";
}

Interpolation parse_interpolation(const std::string& text, const std::string& key) {
    if (text == "smoothstep") return Interpolation::kSmoothstep;
    if (text == "linear") return Interpolation::kLinear;
    throw ConfigError("key '" + key + "': expected 'smoothstep' or 'linear', got '" + text + "'");
}
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

using IndexAccessor = openvdb::tree::ValueAccessor<const IndexTree, false>;

openvdb::Coord to_coord(const Eigen::Vector3i& v) { return openvdb::Coord(v.x(), v.y(), v.z()); }

/// The cell of `p` on a level: its (0,0,0) corner in the level's index space, and p's position
/// inside the cell in t.
openvdb::Coord cell_base_inv(const LevelIndex& level, double inv, const Eigen::Vector3f& p,
                             float t[3]) {
    const openvdb::Coord& shift = level.shift;
    const double gx = p.x() * inv, gy = p.y() * inv, gz = p.z() * inv;
    const double fx = std::floor(gx), fy = std::floor(gy), fz = std::floor(gz);
    t[0] = static_cast<float>(gx - fx);
    t[1] = static_cast<float>(gy - fy);
    t[2] = static_cast<float>(gz - fz);
    return openvdb::Coord(static_cast<int>(fx) + shift.x(), static_cast<int>(fy) + shift.y(),
                          static_cast<int>(fz) + shift.z());
}

/// As cell_base_inv() with inv = 1 / cell_size_m.
openvdb::Coord cell_base(const LevelIndex& level, double cell_size_m, const Eigen::Vector3f& p,
                         float t[3]) {
    return cell_base_inv(level, 1.0 / cell_size_m, p, t);
}

/// The rows of the 8 corners of the cell at `base`; false if one of them is not allocated.
bool cell_rows(IndexAccessor& accessor, const LevelIndex& level, const openvdb::Coord& base,
               std::int32_t rows[8]) {
    constexpr int kLeafMask = static_cast<int>(IndexLeaf::DIM) - 1;
    if ((base.x() & kLeafMask) != kLeafMask && (base.y() & kLeafMask) != kLeafMask &&
        (base.z() & kLeafMask) != kLeafMask) {
        // All 8 corners lie in one leaf node (7 cells in 8 per axis): one leaf probe, and the
        // corners' voxel offsets follow from the base's (x major, z minor).
        const IndexLeaf* leaf = accessor.probeConstLeaf(base);
        if (!leaf) return false;
        const auto& mask = leaf->getValueMask();
        const LeafSlots& slots = level.leaves[leaf->transientData()];
        const openvdb::Index n0 = IndexLeaf::coordToOffset(base);
        for (int c = 0; c < 8; ++c) {
            const openvdb::Index n = n0 + (kCornerOffset[c][0] << (2 * IndexLeaf::LOG2DIM)) +
                                     (kCornerOffset[c][1] << IndexLeaf::LOG2DIM) +
                                     kCornerOffset[c][2];
            const openvdb::Index w = n >> 6, bit = n & 63;
            const openvdb::Index64 word = mask.getWord<openvdb::Index64>(w);
            if (!((word >> bit) & 1)) return false;
            const std::uint64_t before_word = w ? (slots.word_prefix >> (9 * (w - 1))) & 511u : 0u;
            rows[c] = level.row_of_slot(
                slots.first_slot + before_word +
                openvdb::util::CountOn(word & ((openvdb::Index64(1) << bit) - 1)));
        }
        return true;
    }
    for (int c = 0; c < 8; ++c) {
        const std::int32_t row =
            index_row(accessor, level,
                      base.offsetBy(kCornerOffset[c][0], kCornerOffset[c][1], kCornerOffset[c][2]));
        if (row < 0) return false;
        rows[c] = row;
    }
    return true;
}

bool lookup_cell(IndexAccessor& accessor, const LevelIndex& level, double cell_size_m,
                 const Eigen::Vector3f& p, LevelCorners& out) {
    return cell_rows(accessor, level, cell_base(level, cell_size_m, p, out.t), out.rows);
}

FeatureOctreeConfig validated(const FeatureOctreeConfig& config) {
    // OpenVDB's transforms need a scale well away from zero: 0.1 mm to 10 km (the YAML key
    // map.leaf_size_m allows 1 mm to 100 m).
    if (!(config.leaf_size_m >= 1e-4 && config.leaf_size_m <= 1e4)) {
        char got[32];
        std::snprintf(got, sizeof(got), "%g", config.leaf_size_m);
        throw ConfigError(std::string("leaf_size_m must be between 0.0001 and 10000 metres, got ") +
                          got);
    }
    if (config.num_levels < 1 || config.num_levels > 8) {
        throw ConfigError("num_levels must be between 1 and 8, got " +
                          std::to_string(config.num_levels));
    }
    if (config.feature_dim < 1 || config.feature_dim > 64) {
        throw ConfigError("feature_dim must be between 1 and 64, got " +
                          std::to_string(config.feature_dim));
    }
    return config;
}

/// Removes repeated cells, keeping each cell's first occurrence in place. Cells within +-2^20 of
/// the origin on every axis (200 km at 0.2 m) go through an open-addressing set of packed 64-bit
/// keys; farther ones are sorted instead.
void remove_repeated_cells(std::vector<Eigen::Vector3i>& cells) {
    constexpr int kBits = 21;
    constexpr int kBias = 1 << (kBits - 1);
    constexpr std::uint64_t kEmpty = ~std::uint64_t(0);  // no packed key has the top bit set
    const bool packable = std::all_of(cells.begin(), cells.end(), [&](const Eigen::Vector3i& c) {
        return (c.array() >= -kBias).all() && (c.array() < kBias).all();
    });
    if (!packable) {
        std::sort(
            cells.begin(), cells.end(), [](const Eigen::Vector3i& a, const Eigen::Vector3i& b) {
                return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
            });
        cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
        return;
    }
    int bits = 4;
    while ((std::size_t(1) << bits) < 2 * cells.size()) ++bits;
    const std::size_t mask = (std::size_t(1) << bits) - 1;
    std::vector<std::uint64_t> table(mask + 1, kEmpty);
    std::size_t kept = 0;
    for (const Eigen::Vector3i& c : cells) {
        const std::uint64_t key = (std::uint64_t(c.x() + kBias) << (2 * kBits)) |
                                  (std::uint64_t(c.y() + kBias) << kBits) |
                                  std::uint64_t(c.z() + kBias);
        std::size_t slot = static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> (64 - bits));
        while (table[slot] != kEmpty && table[slot] != key) slot = (slot + 1) & mask;
        if (table[slot] == key) continue;
        table[slot] = key;
        cells[kept++] = c;
    }
    cells.resize(kept);
}

/// Largest multiple of `step` not above `v` (step > 0).
int floor_to_multiple(int v, int step) {
    const int q = v / step;
    return (q * step > v ? q - 1 : q) * step;
}

}  // namespace

openvdb::Coord choose_index_shift(const openvdb::CoordBBox& first_cells) {
    constexpr int kRootChildDim = static_cast<int>(IndexTree::RootNodeType::ChildNodeType::DIM);
    constexpr int kLeafDim = static_cast<int>(IndexLeaf::DIM);
    constexpr int kMiddle = kRootChildDim / 2;  // a multiple of the leaf size
    const openvdb::Coord lo = first_cells.min(), hi = first_cells.max();
    // Whole leaves in x and y keep the leaf alignment of the unshifted grid there.
    return openvdb::Coord(kMiddle - floor_to_multiple(lo.x() + (hi.x() - lo.x()) / 2, kLeafDim),
                          kMiddle - floor_to_multiple(lo.y() + (hi.y() - lo.y()) / 2, kLeafDim),
                          kMiddle - lo.z());
}

namespace {

/// Active voxels before each mask word of `leaf` (LeafSlots::word_prefix).
std::uint64_t word_prefix_of(const IndexLeaf& leaf) {
    std::uint64_t prefix = 0;
    openvdb::Index64 before = 0;
    const auto& mask = leaf.getValueMask();
    for (openvdb::Index w = 1; w < IndexLeaf::NodeMaskType::WORD_COUNT; ++w) {
        before += openvdb::util::CountOn(mask.getWord<openvdb::Index64>(w - 1));
        prefix |= before << (9 * (w - 1));
    }
    return prefix;
}

/// Sets level.identity_base (feature_octree_impl.hpp) from `rows`: one pass, stopped at the
/// first slot that breaks the rule.
void update_identity_base(LevelIndex& level) {
    level.identity_base = -1;
    if (level.dead_slots != 0 || level.rows.empty() || level.rows[0] < 0) return;
    const std::int64_t base = level.rows[0];
    for (std::size_t s = 1; s < level.rows.size(); ++s) {
        if (level.rows[s] != base + std::int64_t(s)) return;
    }
    level.identity_base = base;
}

/// Packs every leaf in tree order into new, exactly sized arrays: the corners active in `fresh`
/// (may be null) get new_row(), the others keep their rows.
void pack_all_rows(LevelIndex& level, const IndexTree* fresh, const NewCornerRow& new_row) {
    std::vector<std::int32_t> rows;
    rows.reserve(level.grid->tree().activeVoxelCount());
    std::vector<LeafSlots> leaves;
    leaves.reserve(level.grid->tree().leafCount());
    std::unique_ptr<IndexAccessor> fresh_accessor;
    if (fresh) fresh_accessor = std::make_unique<IndexAccessor>(*fresh);
    for (auto leaf = level.grid->tree().beginLeaf(); leaf; ++leaf) {
        const IndexLeaf* fresh_leaf =
            fresh_accessor ? fresh_accessor->probeConstLeaf(leaf->origin()) : nullptr;
        const openvdb::Index count = leaf->onVoxelCount();
        const bool had_corners = !fresh_leaf || fresh_leaf->onVoxelCount() < count;
        // The leaf's previous first slot (its transient data indexes the previous leaves).
        std::size_t old_slot = had_corners ? level.leaves[leaf->transientData()].first_slot : 0;
        LeafSlots slots;
        slots.first_slot = static_cast<std::uint32_t>(rows.size());
        slots.word_prefix = word_prefix_of(*leaf);
        if (!fresh_leaf) {
            const auto begin = level.rows.begin() + static_cast<std::ptrdiff_t>(old_slot);
            rows.insert(rows.end(), begin, begin + count);
        } else {
            // Old corners keep their order (and rows); new ones are slotted in between.
            for (auto voxel = leaf->cbeginValueOn(); voxel; ++voxel) {
                if (fresh_leaf->isValueOn(voxel.pos())) {
                    rows.push_back(new_row(voxel.getCoord() - level.shift));
                } else {
                    rows.push_back(level.rows[old_slot++]);
                }
            }
        }
        leaf->setTransientData(static_cast<openvdb::Index32>(leaves.size()));
        leaves.push_back(slots);
    }
    level.rows.swap(rows);
    level.leaves.swap(leaves);
    level.dead_slots = 0;
    update_identity_base(level);
}

}  // namespace

void compact_rows(LevelIndex& level) {
    if (level.dead_slots == 0 && level.rows.capacity() == level.rows.size() &&
        level.leaves.capacity() == level.leaves.size()) {
        return;
    }
    pack_all_rows(level, nullptr, {});
}

void repack_rows(LevelIndex& level, const IndexTree* fresh, const NewCornerRow& new_row) {
    if (!fresh) return;
    if (level.leaves.empty() || fresh == &level.grid->tree()) {
        pack_all_rows(level, fresh, new_row);
        return;
    }
    openvdb::tree::ValueAccessor<IndexTree> accessor(level.grid->tree());
    for (auto fresh_leaf = fresh->cbeginLeaf(); fresh_leaf; ++fresh_leaf) {
        IndexLeaf* leaf = accessor.probeLeaf(fresh_leaf->origin());
        if (!leaf) throw Error("repack_rows: a new corner's leaf is missing from the level's grid");
        const openvdb::Index count = leaf->onVoxelCount();
        const openvdb::Index added = fresh_leaf->onVoxelCount();
        const bool had_corners = added < count;
        if (level.rows.size() + count > std::numeric_limits<std::uint32_t>::max()) {
            throw Error("feature map level exceeds 2^32 corner slots; use a larger leaf size");
        }
        LeafSlots slots;
        slots.first_slot = static_cast<std::uint32_t>(level.rows.size());
        slots.word_prefix = word_prefix_of(*leaf);
        if (had_corners) {
            LeafSlots& previous = level.leaves[leaf->transientData()];
            std::size_t old_slot = previous.first_slot;
            for (auto voxel = leaf->cbeginValueOn(); voxel; ++voxel) {
                if (fresh_leaf->isValueOn(voxel.pos())) {
                    level.rows.push_back(new_row(voxel.getCoord() - level.shift));
                } else {
                    const std::int32_t row = level.rows[old_slot++];
                    level.rows.push_back(row);
                }
            }
            level.dead_slots += count - added;
            previous = slots;
        } else {
            for (auto voxel = leaf->cbeginValueOn(); voxel; ++voxel) {
                level.rows.push_back(new_row(voxel.getCoord() - level.shift));
            }
            leaf->setTransientData(static_cast<openvdb::Index32>(level.leaves.size()));
            level.leaves.push_back(slots);
        }
    }
    if (level.dead_slots > level.rows.size() - level.dead_slots) {
        compact_rows(level);
    } else {
        update_identity_base(level);
    }
}

namespace {
/// The seed of a corner's initial feature: a hash of the map's seed, the level and the corner.
std::uint64_t corner_seed(std::uint64_t seed, int level, const openvdb::Coord& corner) {
    std::uint64_t h = mix64(seed);
    h = mix64(h ^ static_cast<std::uint64_t>(level));
    h = mix64(h ^ static_cast<std::uint32_t>(corner.x()));
    h = mix64(h ^ static_cast<std::uint32_t>(corner.y()));
    h = mix64(h ^ static_cast<std::uint32_t>(corner.z()));
    return h;
}

/// feature_dim draws from N(0, init_std^2) with `rng`.
void draw_feature(Mt19937_64Prefix& rng, float init_std, float* out, int feature_dim) {
    std::normal_distribution<float> normal(0.0f, init_std);
    for (int i = 0; i < feature_dim; ++i) out[i] = normal(rng);
}
}  // namespace

void FeatureOctree::initial_feature(std::uint64_t seed, int level, const Eigen::Vector3i& corner,
                                    float init_std, float* out, int feature_dim) {
    // std::mt19937_64's outputs for the corner's seed, without its whole state.
    Mt19937_64Prefix rng(corner_seed(seed, level, to_coord(corner)));
    draw_feature(rng, init_std, out, feature_dim);
}

FeatureOctree::FeatureOctree(const FeatureOctreeConfig& config)
    : config_(validated(config)),
      features_(config.feature_dim, config.feature_precision),
      impl_(std::make_unique<FeatureOctreeImpl>()) {
    for (int level = 0; level < config.num_levels; ++level) {
        LevelIndex index;
        index.grid = IndexGrid::create(false);
        index.grid->setName("feature_level_" + std::to_string(level));
        index.grid->setTransform(
            openvdb::math::Transform::createLinearTransform(cell_size_m(level)));
        index.grid->setGridClass(openvdb::GRID_UNKNOWN);
        impl_->levels.push_back(std::move(index));
    }
}

FeatureOctree::~FeatureOctree() = default;
FeatureOctree::FeatureOctree(FeatureOctree&&) noexcept = default;
FeatureOctree& FeatureOctree::operator=(FeatureOctree&&) noexcept = default;

FeatureOctree FeatureOctree::clone() const {
    FeatureOctree copy(config_);
    copy.features_ = features_;
    copy.impl_->levels = impl_->levels;
    // The level structs share their grids after the copy above: each gets its own (a leaf's
    // transient data, its index into `leaves`, is copied with it).
    for (LevelIndex& level : copy.impl_->levels) {
        if (level.grid) level.grid = level.grid->deepCopy();
    }
    return copy;
}

double FeatureOctree::cell_size_m(int level) const {
    return config_.leaf_size_m * static_cast<double>(1 << level);
}

std::size_t FeatureOctree::allocate_cells(const std::vector<Eigen::Vector3f>& points_map) {
    std::vector<std::unique_ptr<IndexTree>> fresh_trees(config_.num_levels);
    std::vector<const IndexTree*> fresh(config_.num_levels, nullptr);
    std::size_t added = 0;
    // Points and cells are handled in blocks of this many, in parallel; every result is then
    // combined in block order, so the map does not depend on the thread count.
    constexpr std::size_t kBlock = 4096;
    for (int level = 0; level < config_.num_levels; ++level) {
        // Each block of points lists its distinct cells, so that each corner is visited about
        // once per cell (a cell shared by two blocks is visited twice, which changes nothing):
        // the set of missing corners does not depend on the order in which they are found.
        const double inv = 1.0 / cell_size_m(level);
        const double margin_m = config_.allocation_margin_ratio * config_.leaf_size_m;
        const std::size_t point_blocks = (points_map.size() + kBlock - 1) / kBlock;
        std::vector<std::vector<Eigen::Vector3i>> block_cells(point_blocks);
        tbb::parallel_for(std::size_t(0), point_blocks, [&](std::size_t b) {
            std::vector<Eigen::Vector3i>& out = block_cells[b];
            out.reserve(kBlock * 2);
            const std::size_t end = std::min(points_map.size(), (b + 1) * kBlock);
            for (std::size_t i = b * kBlock; i < end; ++i) {
                const Eigen::Vector3f& p = points_map[i];
                int lo[3], hi[3];
                for (int a = 0; a < 3; ++a) {
                    lo[a] = static_cast<int>(std::floor((p[a] - margin_m) * inv));
                    hi[a] = static_cast<int>(std::floor((p[a] + margin_m) * inv));
                }
                for (int x = lo[0]; x <= hi[0]; ++x) {
                    for (int y = lo[1]; y <= hi[1]; ++y) {
                        for (int z = lo[2]; z <= hi[2]; ++z) out.emplace_back(x, y, z);
                    }
                }
            }
            remove_repeated_cells(out);
        });
        const bool any_cell = std::any_of(block_cells.begin(), block_cells.end(),
                                          [](const auto& cells) { return !cells.empty(); });
        if (!any_cell) continue;

        LevelIndex& index = impl_->levels[level];
        if (!index.shift_chosen) {
            openvdb::CoordBBox bbox;
            for (const auto& cells : block_cells) {
                for (const auto& cell : cells) {
                    bbox.expand(to_coord(cell));
                    bbox.expand(to_coord(cell).offsetBy(1));
                }
            }
            index.shift = choose_index_shift(bbox);
            index.shift_chosen = true;
            index.grid->transform().postTranslate(-index.shift.asVec3d() * cell_size_m(level));
        }
        // The corners not yet in the grid, found in parallel (the grid is only read); a corner
        // shared by several cells may be listed more than once.
        std::vector<std::vector<openvdb::Coord>> missing(point_blocks);
        tbb::parallel_for(std::size_t(0), point_blocks, [&](std::size_t b) {
            IndexAccessor reader(index.grid->tree());
            for (const Eigen::Vector3i& cell : block_cells[b]) {
                const openvdb::Coord origin = to_coord(cell) + index.shift;
                for (const auto& offset : kCornerOffset) {
                    const openvdb::Coord ijk = origin.offsetBy(offset[0], offset[1], offset[2]);
                    if (!reader.isValueOn(ijk)) missing[b].push_back(ijk);
                }
            }
            std::vector<Eigen::Vector3i>().swap(block_cells[b]);
        });
        auto accessor = index.grid->getAccessor();
        fresh_trees[level] = std::make_unique<IndexTree>(false);
        openvdb::tree::ValueAccessor<IndexTree> fresh_accessor(*fresh_trees[level]);
        std::size_t added_here = 0;
        for (const auto& block : missing) {
            for (const openvdb::Coord& ijk : block) {
                if (accessor.isValueOn(ijk)) continue;
                accessor.setValueOn(ijk);
                fresh_accessor.setValueOn(ijk);
                ++added_here;
            }
        }
        if (added_here > 0) fresh[level] = fresh_trees[level].get();
        added += added_here;
    }
    if (added == 0) return 0;
    const std::size_t old_rows = num_corners();
    if (old_rows + added >= static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
        throw Error("feature map exceeds 2^31 corners; use a larger leaf size");
    }
    // New corners get rows appended to the table, in tree order; existing rows do not move. Their
    // initial values (a hash of the corner, see initial_feature) are drawn afterwards, in
    // parallel.
    features_.resize(old_rows + added);
    struct NewCorner {
        openvdb::Coord corner;
        int level;
    };
    std::vector<NewCorner> new_corners;
    new_corners.reserve(added);
    for (int level = 0; level < config_.num_levels; ++level) {
        if (!fresh[level]) continue;
        repack_rows(impl_->levels[level], fresh[level], [&](const openvdb::Coord& corner) {
            new_corners.push_back({corner, level});
            return static_cast<std::int32_t>(old_rows + new_corners.size() - 1);
        });
    }
    const int dim = config_.feature_dim;
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, new_corners.size(), 1024),
        [&](const tbb::blocked_range<std::size_t>& range) {
            // initial_feature() for four corners at a time, their generators
            // seeded side by side (the same values).
            std::vector<float> initial(dim);
            const auto seed_of = [&](std::size_t i) {
                return corner_seed(config_.seed, new_corners[i].level, new_corners[i].corner);
            };
            std::size_t i = range.begin();
            for (; i + 4 <= range.end(); i += 4) {
                Mt19937_64Prefix r0(seed_of(i)), r1(seed_of(i + 1)), r2(seed_of(i + 2)),
                    r3(seed_of(i + 3));
                Mt19937_64Prefix* const generators[4] = {&r0, &r1, &r2, &r3};
                Mt19937_64Prefix::seed_first_outputs(generators);
                for (int g = 0; g < 4; ++g) {
                    draw_feature(*generators[g], config_.init_std, initial.data(), dim);
                    features_.set_row(old_rows + i + g, initial.data());
                }
            }
            for (; i != range.end(); ++i) {
                Mt19937_64Prefix rng(seed_of(i));
                draw_feature(rng, config_.init_std, initial.data(), dim);
                features_.set_row(old_rows + i, initial.data());
            }
        });
    return added;
}

void FeatureOctree::compact_structure() {
    for (LevelIndex& level : impl_->levels) compact_rows(level);
}

void FeatureOctree::renumber_rows_in_tree_order() {
    FeatureTable renumbered(features_.dim(), features_.precision());
    renumbered.resize(features_.num_rows());
    std::size_t next = 0;
    for (LevelIndex& level : impl_->levels) {
        compact_rows(level);  // every slot live, leaves in tree order
        for (std::int32_t& row : level.rows) {
            if (row < 0 || static_cast<std::size_t>(row) >= features_.num_rows() ||
                next >= features_.num_rows()) {
                throw Error("renumber_rows_in_tree_order: corner row " + std::to_string(row) +
                            " outside the feature table of " +
                            std::to_string(features_.num_rows()) + " rows");
            }
            renumbered.copy_rows(features_, static_cast<std::size_t>(row), next, 1);
            row = static_cast<std::int32_t>(next++);
        }
        update_identity_base(level);
    }
    if (next != features_.num_rows()) {
        throw Error("renumber_rows_in_tree_order: " + std::to_string(next) + " corners but " +
                    std::to_string(features_.num_rows()) + " feature rows");
    }
    features_ = std::move(renumbered);
}

bool FeatureOctree::find_cell(int level, const Eigen::Vector3f& point_map,
                              LevelCorners& out) const {
    const LevelIndex& index = impl_->levels[level];
    IndexAccessor accessor(index.grid->tree());
    return lookup_cell(accessor, index, cell_size_m(level), point_map, out);
}

bool FeatureOctree::has_leaf_cell(const Eigen::Vector3i& cell) const {
    const LevelIndex& index = impl_->levels[0];
    IndexAccessor accessor(index.grid->tree());
    const openvdb::Coord origin = to_coord(cell) + index.shift;
    for (const auto& offset : kCornerOffset) {
        if (!accessor.isValueOn(origin.offsetBy(offset[0], offset[1], offset[2]))) return false;
    }
    return true;
}

std::int32_t FeatureOctree::corner_row(int level, const Eigen::Vector3i& corner) const {
    const LevelIndex& index = impl_->levels.at(level);
    IndexAccessor accessor(index.grid->tree());
    return index_row(accessor, index, to_coord(corner) + index.shift);
}

std::size_t FeatureOctree::copy_shared_features(const FeatureOctree& source) {
    if (source.num_levels() != num_levels() || source.feature_dim() != feature_dim() ||
        source.feature_precision() != feature_precision() ||
        source.config().leaf_size_m != config().leaf_size_m) {
        throw ConfigError(
            "copying features between octrees needs the same levels, leaf size, feature length "
            "and precision");
    }
    const std::size_t dim = static_cast<std::size_t>(feature_dim());
    const bool half = feature_precision() == FeaturePrecision::kFloat16;
    std::size_t copied = 0;
    for (int l = 0; l < num_levels(); ++l) {
        const LevelIndex& to = impl_->levels[static_cast<std::size_t>(l)];
        const LevelIndex& from = source.impl_->levels[static_cast<std::size_t>(l)];
        if (!to.grid || !from.grid) continue;
        IndexAccessor to_accessor(to.grid->tree());
        IndexAccessor from_accessor(from.grid->tree());
        for (auto it = to.grid->tree().cbeginValueOn(); it; ++it) {
            const openvdb::Coord corner = it.getCoord() - to.shift;
            const std::int32_t from_row = index_row(from_accessor, from, corner + from.shift);
            if (from_row < 0) continue;
            const std::int32_t to_row = index_row(to_accessor, to, it.getCoord());
            if (half) {
                std::copy_n(source.features_.halves() + std::size_t(from_row) * dim, dim,
                            features_.halves() + std::size_t(to_row) * dim);
            } else {
                std::copy_n(source.features_.floats() + std::size_t(from_row) * dim, dim,
                            features_.floats() + std::size_t(to_row) * dim);
            }
            ++copied;
        }
    }
    return copied;
}

std::vector<Eigen::Vector3i> FeatureOctree::cells(int level) const {
    std::vector<Eigen::Vector3i> cells;
    const LevelIndex& index = impl_->levels.at(level);
    IndexAccessor accessor(index.grid->tree());
    for (auto it = index.grid->tree().cbeginValueOn(); it; ++it) {
        // Every allocated cell has its (0,0,0) corner allocated: test each corner as a cell origin.
        const openvdb::Coord c = it.getCoord();
        bool complete = true;
        for (int k = 1; k < 8 && complete; ++k) {
            complete = accessor.isValueOn(
                c.offsetBy(kCornerOffset[k][0], kCornerOffset[k][1], kCornerOffset[k][2]));
        }
        if (complete) {
            const openvdb::Coord cell = c - index.shift;
            cells.emplace_back(cell.x(), cell.y(), cell.z());
        }
    }
    std::sort(cells.begin(), cells.end(), [](const Eigen::Vector3i& a, const Eigen::Vector3i& b) {
        return std::lexicographical_compare(a.data(), a.data() + 3, b.data(), b.data() + 3);
    });
    return cells;
}

std::size_t FeatureOctree::num_corners(int level) const {
    return impl_->levels.at(level).grid->activeVoxelCount();
}

std::size_t FeatureOctree::structure_bytes() const {
    std::size_t bytes = 0;
    for (const auto& level : impl_->levels) bytes += level.memory_bytes();
    return bytes;
}

std::size_t FeatureOctree::memory_bytes() const { return feature_bytes() + structure_bytes(); }

struct CellLookup::Accessors {
    std::vector<IndexAccessor> accessors;
    std::vector<const LevelIndex*> levels;
    /// Per level, the last cell looked up: samples along one ray (and neighbouring voxels of a
    /// bake) often fall in the same cell, above all on the coarser levels.
    struct Recent {
        openvdb::Coord base;
        bool valid = false;
        bool found = false;
        std::int32_t rows[8];
    };
    std::vector<Recent> recent;
    /// Per level, 1 / cell_size_m(level), as cell_base() computes it.
    std::vector<double> inverse_cell_size;
};

CellLookup::CellLookup(const FeatureOctree& octree)
    : octree_(octree), accessors_(std::make_unique<Accessors>()) {
    for (const auto& level : octree.impl().levels) {
        accessors_->accessors.emplace_back(level.grid->tree());
        accessors_->inverse_cell_size.push_back(
            1.0 / octree.cell_size_m(static_cast<int>(accessors_->levels.size())));
        accessors_->levels.push_back(&level);
    }
    accessors_->recent.resize(accessors_->levels.size());
}

CellLookup::~CellLookup() = default;

bool CellLookup::find_cell(int level, const Eigen::Vector3f& point_map, LevelCorners& out) {
    const LevelIndex& index = *accessors_->levels[level];
    const openvdb::Coord base =
        cell_base_inv(index, accessors_->inverse_cell_size[level], point_map, out.t);
    Accessors::Recent& recent = accessors_->recent[level];
    if (!recent.valid || recent.base != base) {
        recent.base = base;
        recent.valid = true;
        recent.found = cell_rows(accessors_->accessors[level], index, base, recent.rows);
    }
    if (recent.found) {
        for (int c = 0; c < 8; ++c) out.rows[c] = recent.rows[c];  // inline, not a memmove call
    }
    return recent.found;
}

}  // namespace shine
