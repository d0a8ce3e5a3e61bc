// The sparse hierarchical feature map (paper Sec. III-A, "Implicit Neural Map Representation").
//
// H levels of node-corner features. Level 0 is the finest (cell size = leaf_size_m); each coarser
// level doubles the cell size. Every level is an OpenVDB grid whose active voxels are the corners
// of that level's cells: voxel (i,j,k) of level l sits at (i,j,k) * cell_size_m(l) in the map
// frame. Each corner owns one row of a contiguous feature table shared by all levels (float32 or
// float16, see feature_table.hpp). The grids keep OpenVDB's sparse, O(1)-average access (through
// ValueAccessors) while the features stay in a dense array that the optimiser, importance weights
// and half-precision storage address by row.
//
// Memory: in memory a level is a topology-only grid (1 bit per voxel, in a 3-3-3 tree) plus the
// corners' rows packed leaf by leaf (a corner's slot is its leaf's first slot plus its rank among
// the leaf's active voxels, as in NanoVDB's index grids): 4 bytes and 1 bit per corner instead of
// OpenVDB Int32 leaves that are mostly empty. The index space of each level is shifted so that
// the map's first scan sits in the middle of one root child and its lowest corner at the bottom of
// a leaf node. On disk (map_file.hpp) every level is a standard Int32Grid of rows.
//
// A cell exists at a level when all 8 of its corners are allocated; allocation adds the cells
// containing the given points at every level. The map only grows; a corner's row never changes.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "shine/map/feature_table.hpp"

namespace shine {

/// How a point's feature is interpolated from its cell's 8 corners (model/interpolation.hpp).
enum class Interpolation : std::uint8_t {
    kSmoothstep,  ///< weights 3t^2 - 2t^3 per axis: C1 across cells, zero slope at the corners
    kLinear,      ///< trilinear weights t per axis: C0 across cells, no flat spots
};

/// "smoothstep" or "linear" (the YAML and file spelling).
const char* to_string(Interpolation interpolation);
/// Parses "smoothstep" / "linear"; throws ConfigError naming `key` otherwise.
Interpolation parse_interpolation(const std::string& text, const std::string& key);

/// Configuration of the feature hierarchy.
struct FeatureOctreeConfig {
    double leaf_size_m = 0.2;  ///< level-0 cell size
    int num_levels = 3;        ///< H
    int feature_dim = 8;       ///< L
    float init_std = 0.05f;    ///< features start as N(0, init_std^2)
    /// Cells are allocated around each point within this margin (as a fraction of the leaf
    /// size), so that a surface point never lies on the border of the allocated region, where
    /// the SDF would be cut off.
    double allocation_margin_ratio = 0.5;
    std::uint64_t seed = 42;  ///< initial features depend only on (seed, level, corner)
    /// Storage of the feature table (training keeps a float32 master copy of a float16 map).
    FeaturePrecision feature_precision = FeaturePrecision::kFloat32;
    /// Interpolation of the corner features inside a cell.
    Interpolation interpolation = Interpolation::kSmoothstep;
};

/// Corner rows and interpolation weights of one query point at one level.
struct LevelCorners {
    std::int32_t rows[8];  ///< feature-table rows of the cell's corners, in (dx,dy,dz) bit order
    float t[3];            ///< position inside the cell, each in [0,1)
};

class FeatureOctreeImpl;

/// H OpenVDB grids of node corners plus the contiguous feature table.
class FeatureOctree {
  public:
    explicit FeatureOctree(const FeatureOctreeConfig& config);
    ~FeatureOctree();
    FeatureOctree(FeatureOctree&&) noexcept;
    FeatureOctree& operator=(FeatureOctree&&) noexcept;
    /// A deep copy (grids, rows, features): a snapshot that stays valid while this one grows.
    FeatureOctree clone() const;

    const FeatureOctreeConfig& config() const { return config_; }
    int num_levels() const { return config_.num_levels; }
    int feature_dim() const { return config_.feature_dim; }
    /// Cell edge length of `level` in metres: leaf_size_m * 2^level.
    double cell_size_m(int level) const;

    /// Allocates, at every level, the cells that the cube of half-size allocation_margin_ratio *
    /// leaf_size_m around each point (map frame) touches. Returns the number of corners added;
    /// their rows are appended to the feature table (existing rows never move). Not thread-safe
    /// with concurrent queries.
    std::size_t allocate_cells(const std::vector<Eigen::Vector3f>& points_map);

    /// Packs the per-corner rows of every level afresh (allocation leaves dead slots behind when
    /// leaves gain corners): for a map that stops growing. Rows and queries are unchanged.
    void compact_structure();
    /// Gives the corners new rows in tree order, level after level (level 0 first; leaf by leaf,
    /// voxel order inside a leaf), each corner's feature moving with it, and packs the structure.
    /// Then the corners of a cell have nearby rows (its features share cache lines) and a
    /// corner's row follows from its place in the tree without a table read. Queries return the
    /// same values; only row numbers change, so anything holding per-row state (a Trainer) must
    /// be made after it. Batch mode calls it once its map is complete.
    void renumber_rows_in_tree_order();

    /// Finds the cell of `level` containing `point_map`; false if any of its corners is missing.
    /// Convenience for single queries; hot loops use a CellLookup per thread.
    bool find_cell(int level, const Eigen::Vector3f& point_map, LevelCorners& out) const;

    /// True when the level-0 cell with integer coordinates `cell` has all 8 corners.
    bool has_leaf_cell(const Eigen::Vector3i& cell) const;

    /// Integer coordinates of every allocated cell of `level` (all 8 corners present), sorted.
    std::vector<Eigen::Vector3i> cells(int level) const;
    /// cells(0).
    std::vector<Eigen::Vector3i> leaf_cells() const { return cells(0); }

    /// Number of allocated corners (= feature rows) over all levels.
    std::size_t num_corners() const { return features_.num_rows(); }
    std::size_t num_corners(int level) const;
    /// Row of the corner with integer coordinates `corner` at `level`, or -1 if not allocated.
    std::int32_t corner_row(int level, const Eigen::Vector3i& corner) const;
    /// Copies into this octree the feature of every corner that `source` has too (same level, same
    /// integer coordinates); corners only this octree has keep theirs. A warm start: a map of the
    /// same scans at slightly different poses starts from what `source` learnt. Throws ConfigError
    /// unless both have the same levels, leaf size, feature length and precision. Returns the
    /// number of corners copied.
    std::size_t copy_shared_features(const FeatureOctree& source);

    /// The feature table, one row per corner. Resizing it is the octree's job.
    FeatureTable& features() { return features_; }
    const FeatureTable& features() const { return features_; }
    FeaturePrecision feature_precision() const { return features_.precision(); }

    /// Bytes of the map in memory: feature table plus the OpenVDB trees' memUsage().
    std::size_t memory_bytes() const;
    std::size_t feature_bytes() const { return features_.bytes(); }
    /// memUsage() of the level grids' trees (counted as for any OpenVDB grid) plus the packed
    /// per-corner rows.
    std::size_t structure_bytes() const;

    /// Access for the serialisation code (map_file.cpp) and tests; others use the API above.
    FeatureOctreeImpl& impl() { return *impl_; }
    const FeatureOctreeImpl& impl() const { return *impl_; }

    /// Features are a pure function of (seed, level, corner): used at allocation and in tests.
    static void initial_feature(std::uint64_t seed, int level, const Eigen::Vector3i& corner,
                                float init_std, float* out, int feature_dim);

  private:
    FeatureOctreeConfig config_;
    FeatureTable features_;
    std::unique_ptr<FeatureOctreeImpl> impl_;
};

/// Cached, non-thread-safe corner lookups into a FeatureOctree: create one per thread or task.
/// Valid while the octree is not modified (allocation invalidates it).
class CellLookup {
  public:
    explicit CellLookup(const FeatureOctree& octree);
    ~CellLookup();
    CellLookup(const CellLookup&) = delete;
    CellLookup& operator=(const CellLookup&) = delete;

    /// As FeatureOctree::find_cell, through cached OpenVDB accessors.
    bool find_cell(int level, const Eigen::Vector3f& point_map, LevelCorners& out);

  private:
    struct Accessors;
    const FeatureOctree& octree_;
    std::unique_ptr<Accessors> accessors_;
};

}  // namespace shine
