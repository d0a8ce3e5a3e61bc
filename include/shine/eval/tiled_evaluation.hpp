// Scoring a city-sized mesh at the street's sampling density: tile by tile.
//
// evaluate_meshes samples both meshes at one density under a budget of samples (mesh_metrics.hpp),
// so a 4 km city (480,000 m^2 of reference surface) would be sampled at 8 points per m^2, one per
// 35 cm square: too sparse for a 10 cm threshold (most predicted samples would be farther than
// that from the nearest reference sample wherever the mesh is). Tiled, the same protocol runs on
// square columns of tile_m x tile_m (world x-y, the reference's frame), each at its own density:
//   - the predicted triangles whose centroid lies in the tile;
//   - the reference triangles whose centroid lies within the tile grown by margin_m (so that a
//     predicted sample near the tile's border finds its reference across it), observed only
//     where the centroid lies in the tile itself (so that each observed face counts once).
// The ratios and means are combined weighted by the area they stand for: precision and accuracy
// by each tile's predicted area, completion and its ratio by its observed reference area; the
// F-score and Chamfer distance come from the combined figures. With movers the ghost areas of the
// tiles add up. A tile with predicted surface but no observed reference surface is not scored;
// its predicted area is reported (unscored_pred_area_m2).
#pragma once

#include <cstddef>

#include "shine/eval/ghost_area.hpp"
#include "shine/eval/mesh_metrics.hpp"
#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/mover_tracks.hpp"

namespace shine {

struct TiledEvalConfig {
    EvalConfig eval;        ///< the protocol, per tile
    double tile_m = 100.0;  ///< edge of a tile (world x-y)
    double margin_m = 1.0;  ///< the reference around a tile that precision may use
    bool show_progress = false;
};

struct TiledEvaluation {
    MeshMetrics metrics;  ///< combined; sample_density_per_m2 is the lowest of the tiles'
    GhostMetrics ghost;   ///< combined (zero without movers)
    std::size_t tiles_scored = 0;
    double unscored_pred_area_m2 = 0.0;  ///< predicted area in tiles with no observed reference
};

/// Scores `pred` against `ref` tile by tile (see the file comment); with `movers` (non-null)
/// also the ghost area. Throws ConfigError for a tile or margin that is not positive and finite
/// (or tiles more than 10^6 across), DataError as evaluate_meshes does and if no tile has observed
/// reference surface.
TiledEvaluation evaluate_meshes_tiled(const TriangleMesh& pred, const TriangleMesh& ref,
                                      const TiledEvalConfig& config,
                                      const MoverTracks* movers = nullptr);

}  // namespace shine
