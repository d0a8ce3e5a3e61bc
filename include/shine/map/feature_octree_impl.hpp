// OpenVDB internals of FeatureOctree, shared only by the sources that (de)serialise its grids: the
// octree itself, the map file (src/model) and the tile merge (src/mapper).
//
// Each level is a topology-only OpenVDB grid (ValueMask voxels) whose active voxels are the
// level's corners, plus one int32 per corner: the corner's feature row. Rows are not stored per
// voxel of a dense leaf buffer (OpenVDB's Int32Grid keeps 512 values per 8^3 leaf however few are
// active) but packed per leaf in voxel order, as NanoVDB's index grids pack values:
//   row = rows[first slot of the leaf + rank of the voxel among the leaf's active voxels],
// the rank being a prefix count kept per leaf plus one popcount of the leaf's value mask.
// A corner therefore costs 4 bytes plus 1 bit of mask, and feature rows stay stable: growing the
// map appends rows, so the optimiser state and importance weights keyed by row never move.
//
// Measured on the bundled street (0.2 m leaf, 439,717 corners), memUsage() of the three level
// trees: Int32 5-4-3 (OpenVDB's default, the previous layout) 17.6 MB; Int32 4-3-3 10.3 MB;
// Int32 4-3-2 7.0 MB; Int32 4-2-2 6.8 MB (4.8 MB with the index shift below); ValueMask 5-4-3
// 9.0 MB; ValueMask 4-3-3 1.66 MB; ValueMask 3-3-3 0.96 MB. As built here (ValueMask 3-3-3 with
// the index shift): trees 0.57 MB + packed rows 1.76 MB + leaf slots 0.05 MB = 2.38 MB. The 3-3-3
// configuration keeps 8^3 leaves (one cache line of mask per leaf) and small 8^3 internal nodes
// (4 KB each), so a map straddling a root-node boundary costs a few KB, not the ~270 KB of a
// 32^3 internal node of the default tree.
#pragma once

#include <openvdb/openvdb.h>

#include <cstdint>
#include <functional>
#include <vector>

namespace shine {

/// Topology of one level: ValueMask voxels in a 3-3-3 tree (root children span 512 voxels).
using IndexTree = openvdb::tree::Tree4<openvdb::ValueMask, 3, 3, 3>::Type;
using IndexGrid = openvdb::Grid<IndexTree>;
using IndexLeaf = IndexTree::LeafNodeType;

/// Where a leaf's corners sit in LevelIndex::rows, with NanoVDB's per-word prefix counts so that
/// a voxel's rank inside its leaf is one popcount (not up to eight).
struct LeafSlots {
    std::uint64_t word_prefix = 0;  ///< active voxels before mask word w (w = 1..7), 9 bits each
    std::uint32_t first_slot = 0;   ///< slot of the leaf's first active voxel
};

/// One level: its grid (index space = corner coordinates + shift), the shift and the packed rows.
struct LevelIndex {
    IndexGrid::Ptr grid;
    /// Index-space coordinates = corner coordinates + shift; chosen at the level's first
    /// allocation (choose_index_shift) and stored in map files.
    openvdb::Coord shift{0, 0, 0};
    bool shift_chosen = false;
    /// Feature row of every corner, leaf by leaf, in voxel order inside a leaf. Packed in tree
    /// order by a full repack; a leaf that gains corners later is re-packed at the end, leaving
    /// dead slots behind (repack_rows compacts when they outnumber the live ones).
    std::vector<std::int32_t> rows;
    /// Per leaf; a leaf's transient data is its index here.
    std::vector<LeafSlots> leaves;
    std::size_t dead_slots = 0;  ///< slots of `rows` no leaf refers to
    /// When every slot s holds row identity_base + s (the level's corners were given rows in
    /// tree order in one allocation, as a batch map's are, and no slot is dead): that base, and
    /// a corner's row is found without reading `rows` (its loads were half of a training step's
    /// cell lookups). -1 otherwise. Kept by repack_rows() and compact_rows().
    std::int64_t identity_base = -1;

    /// The row in slot `slot`.
    std::int32_t row_of_slot(std::size_t slot) const {
        return identity_base >= 0 ? static_cast<std::int32_t>(identity_base + std::int64_t(slot))
                                  : rows[slot];
    }

    /// Bytes of the grid's tree (memUsage(), as for any OpenVDB grid), the packed rows and the
    /// per-leaf slots.
    std::size_t memory_bytes() const {
        return grid->memUsage() + rows.capacity() * sizeof(std::int32_t) +
               leaves.capacity() * sizeof(LeafSlots);
    }
};

class FeatureOctreeImpl {
  public:
    std::vector<LevelIndex> levels;
};

/// Shift that puts the centre of `first_cells` (the first allocation of a level, in corner
/// coordinates) in the middle of a root child in x and y, and its lowest corner at the bottom of
/// a leaf node in the middle of a root child in z: the map then spans as few upper nodes as
/// possible as it grows around its first scan, and level ground below the sensor lies in one
/// layer of leaf nodes instead of straddling two.
openvdb::Coord choose_index_shift(const openvdb::CoordBBox& first_cells);

/// Slot in `level.rows` of the voxel `ijk` (index space), or -1 when it is not active.
template <typename AccessorT>
inline std::int32_t index_slot(AccessorT& accessor, const LevelIndex& level,
                               const openvdb::Coord& ijk) {
    const IndexLeaf* leaf = accessor.probeConstLeaf(ijk);
    if (!leaf) return -1;
    const openvdb::Index n = IndexLeaf::coordToOffset(ijk);
    const openvdb::Index w = n >> 6, bit = n & 63;
    const openvdb::Index64 word = leaf->getValueMask().template getWord<openvdb::Index64>(w);
    if (!((word >> bit) & 1)) return -1;
    const LeafSlots& slots = level.leaves[leaf->transientData()];
    const std::uint64_t before_word = w ? (slots.word_prefix >> (9 * (w - 1))) & 511u : 0u;
    return static_cast<std::int32_t>(
        slots.first_slot + before_word +
        openvdb::util::CountOn(word & ((openvdb::Index64(1) << bit) - 1)));
}

/// Feature row of the voxel `ijk` (index space) of `level`, or -1 when it is not active.
template <typename AccessorT>
inline std::int32_t index_row(AccessorT& accessor, const LevelIndex& level,
                              const openvdb::Coord& ijk) {
    const std::int32_t slot = index_slot(accessor, level, ijk);
    return slot < 0 ? -1 : level.row_of_slot(static_cast<std::size_t>(slot));
}

/// Returns the feature row of a corner (corner coordinates) that has just been activated.
using NewCornerRow = std::function<std::int32_t(const openvdb::Coord& corner)>;

/// Updates `level.rows` and `level.leaves` after the voxels active in `fresh` (null: none) were
/// activated in the level's grid: corners that existed keep their rows, new ones get
/// `new_row(corner)`, called in tree order. Only the leaves that gained corners are re-packed (at
/// the end of `rows`), so the cost follows the new corners, not the map; when the dead slots this
/// leaves outnumber the live ones, or for a first allocation, all leaves are packed afresh in tree
/// order (and every leaf's transient data set to its index).
void repack_rows(LevelIndex& level, const IndexTree* fresh, const NewCornerRow& new_row);

/// Packs every leaf afresh, in tree order, with `rows` sized exactly: no dead slots.
void compact_rows(LevelIndex& level);

}  // namespace shine
