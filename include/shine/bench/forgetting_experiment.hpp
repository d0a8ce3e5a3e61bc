// The forgetting experiment behind `shine forgetting` (paper Sec. III, "Incremental Mapping
// Without Forgetting", and Fig. 7): the same sequence mapped incrementally with and without the
// importance-weight regulariser (and optionally in batch mode as the reference), each evaluated at
// the end of the run on the whole map and on the part seen in the first quarter of the run.
//
// The early region. A reference triangle counts as seen in the first quarter when it was observed
// at all (the reference's face_observed flags, as in the whole-map evaluation) and its centroid
// lies in a region_voxel_m voxel that holds at least one preprocessed point (the points the mapper
// trained on) of the first ceil(early_fraction * N) scans. Completion and completion ratio run
// over those triangles; precision and accuracy over the predicted triangles in that region grown
// by one voxel, against the whole reference (region_crop.hpp). Seeing a surface is what the
// scans' points show, so the definition needs no ray casting and works for any reference mesh.
//
// Outputs in OUT: regularized/, unregularized/ (and batch/) with map.vdb, surface.vdb, mesh.ply
// as `shine map` writes them; forgetting.json (settings, metrics, median seconds per frame and
// thread count per run); forgetting.png (the meshes side by side, whole map above and the early
// region below, coloured by the distance to the observed reference).
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "shine/eval/mesh_metrics.hpp"
#include "shine/eval/region_crop.hpp"
#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/mapper_config.hpp"

namespace shine {

struct ForgettingConfig {
    /// Both incremental runs use this configuration; the regularised one with its
    /// incremental.importance.regularization_weight (> 0), the other with 0. Batch mode (if
    /// with_batch) uses it as `shine map` would.
    MapperConfig mapper;
    double early_fraction = 0.25;  ///< the first quarter of the frames defines the early region
    double region_voxel_m = 1.0;   ///< voxel of the early region
    EvalConfig eval;
    bool with_batch = false;
    int image_panel_width = 800;  ///< pixels per panel of forgetting.png
};

/// One mapped and evaluated run.
struct ForgettingRun {
    std::string name;  ///< "unregularized", "regularized" or "batch"
    float regularization_weight = 0.0f;
    MeshMetrics whole;
    MeshMetrics early;
    double median_frame_seconds = 0.0;  ///< incremental runs; 0 for batch
    double seconds = 0.0;               ///< mapping and products, wall clock
    std::size_t map_bytes = 0;
    TriangleMesh mesh;  ///< world frame
};

struct ForgettingReport {
    std::vector<ForgettingRun> runs;
    std::size_t frames = 0;
    std::size_t early_frames = 0;
    double early_reference_area_m2 = 0.0;  ///< observed reference area in the early region
    int threads = 0;                       ///< TBB's thread limit during the runs
};

/// Runs the experiment on `sequence` against `reference` (with face_observed flags) and writes
/// the outputs listed in the file comment into `out_dir`. Throws ConfigError if the configured
/// regularisation weight is 0 or early_fraction is not in (0, 1], and what the mapping and
/// evaluation throw.
ForgettingReport run_forgetting_experiment(const ForgettingConfig& config,
                                           const ScanSequence& sequence,
                                           const TriangleMesh& reference,
                                           const std::filesystem::path& out_dir);

/// The report as JSON text (what forgetting.json holds).
std::string forgetting_report_json(const ForgettingReport& report, const ForgettingConfig& config);

/// A table for terminals: one line per run and region (cm and %).
std::string format_forgetting_report(const ForgettingReport& report);

}  // namespace shine
