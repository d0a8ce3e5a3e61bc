// Ghosts of moving objects in a map: the predicted surface that lies off the static scene and
// inside the volume some mover swept during the sequence (io/mover_tracks.hpp), measured as an
// area and as a share of the observed static surface.
//
//   1. Sample the predicted mesh uniformly at the protocol's density d (mesh_metrics.hpp), with no
//      downsampling, so that every sample stands for 1/d m^2 of surface.
//   2. A sample is off the static scene if it is at least threshold_m from the reference surface
//      (the nearest of the reference's downsampled samples, as for precision).
//   3. It is a ghost if it is also inside a mover's swept volume: the union over the path of the
//      mover's box grown by swept_margin_m. For a path segment with a constant yaw this is tested
//      exactly (the box slid along the segment: one interval per axis); a segment that turns is
//      cut into pieces whose yaw changes by at most 0.5 deg, each slid at its mean yaw.
//   4. ghost_area_m2 = ghost samples / d; ghost_share = ghost_area_m2 / observed reference area.
//
// The margin (default: the threshold) admits the surface a mapper draws just outside a mover's
// box, as it does just outside any observed surface.
#pragma once

#include <cstddef>
#include <string>

#include "shine/eval/mesh_metrics.hpp"
#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/mover_tracks.hpp"

namespace shine {

/// The ghost measure's parameters: the protocol's sampling and threshold, and the box margin.
struct GhostConfig {
    EvalConfig eval;               ///< threshold_m, sampling density and budget, downsampling, seed
    double swept_margin_m = -1.0;  ///< grows each mover's box; < 0: eval.threshold_m
};

/// Result of measure_ghost_area(); areas in m^2, shares in [0, inf).
struct GhostMetrics {
    double ghost_area_m2 = 0.0;         ///< predicted surface off the static scene, in a swept box
    double ghost_share = 0.0;           ///< ghost_area_m2 / ref_observed_area_m2
    double off_static_area_m2 = 0.0;    ///< all predicted surface off the static scene
    double pred_area_m2 = 0.0;          ///< estimate from the samples (sample count / density)
    double ref_observed_area_m2 = 0.0;  ///< observed static reference surface
    double threshold_m = 0.0;
    double swept_margin_m = 0.0;
    double sample_density_per_m2 = 0.0;
    std::size_t num_movers = 0;
    std::size_t pred_samples = 0;
    std::size_t ghost_samples = 0;
};

/// Whether `point` (reference frame) lies in the volume `mover` swept along its whole path, its
/// box grown by `margin_m` on every side.
bool inside_swept_volume(const MoverTrack& mover, const Eigen::Vector3d& point, double margin_m);

/// Measures the ghosts of `pred` against the static reference `ref` and the movers of `tracks`
/// (positions in ref's frame; pred is moved into it as evaluate_meshes does). Throws DataError as
/// evaluate_meshes for a reference without observed surface or a malformed mesh, and ConfigError
/// for an invalid config.
GhostMetrics measure_ghost_area(const TriangleMesh& pred, const TriangleMesh& ref,
                                const MoverTracks& tracks, const GhostConfig& config = {});

/// A multi-line block for terminals (areas in m^2, shares in %).
std::string format_ghost_metrics(const GhostMetrics& metrics);

/// One JSON object with every field of `metrics` under its C++ name.
std::string ghost_metrics_to_json(const GhostMetrics& metrics);

}  // namespace shine
