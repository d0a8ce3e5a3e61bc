// Merges neural maps of spatial tiles (each mapped from the scans that see it, cropped to its core
// box grown by an overlap) into one map, seamless at the tile borders.
//
// Every tile must be mapped with the same frame origin, leaf size, levels, feature size, feature
// precision and IDENTICAL decoder weights (incremental mode's frozen, pretrained decoder): a
// corner's feature then means the same thing in every tile, and a merged map can take each
// corner's feature row from one tile. The merged map allocates the union of the tiles' cells (=
// the union of their corners, since a tile only ever allocates whole cells) and takes the feature
// of a corner at level l, world position origin + corner * cell_size(l), from
//   1. the tile whose core box contains the corner's (x, y) (cores are half-open and partition
//      the plane), if that tile has the corner;
//   2. otherwise the tile, among those that have it, whose core is nearest to the corner in
//      (x, y) (the first listed on a tie). This covers corners outside every core and corners
//      that the owner did not allocate (e.g. seen only from scans the owner did not use).
// The merged SDF is one feature field read through one decoder, so it is continuous across tile
// borders by construction; inside each core it equals the owner tile's SDF except within one
// cell of level l (leaf_size * 2^l) of the border, where the interpolation mixes both tiles'
// features. Since both tiles were trained on the same points there (the overlap), the features
// agree closely (the seam check in docs/tiles.md measures it).
//
// Tiles are loaded and folded in one at a time: memory is the merged map plus one tile.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "shine/model/neural_sdf.hpp"

namespace shine {

/// A tile's core: the half-open world box [x_min_m, x_max_m) x [y_min_m, y_max_m), unbounded in
/// z. Bounds may be infinite (outer tiles of a grid).
struct TileCore {
    double x_min_m = 0.0;
    double y_min_m = 0.0;
    double x_max_m = 0.0;
    double y_max_m = 0.0;

    /// True when the world point (x, y) lies in the half-open box.
    bool contains(double x_m, double y_m) const {
        return x_m >= x_min_m && x_m < x_max_m && y_m >= y_min_m && y_m < y_max_m;
    }
    /// Euclidean distance in (x, y) from the point to the box (0 inside or on its border).
    double distance_m(double x_m, double y_m) const;
};

/// One input of a merge: a tile's map.vdb and its core box.
struct MapTile {
    std::filesystem::path map_path;
    TileCore core_world_m;
};

/// What a merge took from each tile.
struct TileMergeStats {
    std::filesystem::path map_path;
    std::size_t corners = 0;        ///< corners of the tile's map
    std::size_t corners_taken = 0;  ///< merged corners whose feature comes from this tile
};

/// Summary of a merge.
struct MergeStats {
    std::vector<TileMergeStats> tiles;  ///< in input order
    std::size_t corners = 0;            ///< corners of the merged map (union over tiles)
    /// Merged corners whose owner (the tile whose core contains them) did not have them, or
    /// that lie in no core, and were taken from the nearest tile that had them.
    std::size_t fallback_corners = 0;
};

/// A merged map, the configuration text of the first tile (provenance; its crop is the first
/// tile's) and the summary.
struct MergedMap {
    NeuralSdf sdf;
    std::string first_tile_config_text;
    MergeStats stats;
};

/// Parses "PATH:xmin,ymin,xmax,ymax" (world metres; the last ':' separates the path, so paths
/// may contain ':'; "inf" and "-inf" are accepted). Throws ConfigError quoting `spec` otherwise.
MapTile parse_tile_spec(const std::string& spec);

/// Reads a JSON manifest {"tiles": [{"map": "PATH", "core_world_m": [xmin, ymin, xmax, ymax]},
/// ...]}; relative map paths are relative to the manifest's directory. Bounds may be the strings
/// "inf" / "-inf". Throws IoError naming the file and the entry on missing or malformed input.
std::vector<MapTile> read_tile_manifest(const std::filesystem::path& path);

/// Checks that the cores are valid (min < max, no NaN) and pairwise disjoint (no overlap of
/// positive area), and that no map is listed twice. Throws ConfigError naming the files.
void check_tile_cores(const std::vector<MapTile>& tiles);

/// Merges the tiles' maps as described at the top of this file. Throws ConfigError when no tile
/// is given or the cores are invalid (check_tile_cores), IoError naming the file when a map cannot
/// be read, and DataError naming the file and the setting when a tile's map differs from the
/// first tile's in origin, leaf size, levels, feature dimension, precision, decoder layers or
/// decoder weights.
MergedMap merge_tile_maps(const std::vector<MapTile>& tiles);

}  // namespace shine
