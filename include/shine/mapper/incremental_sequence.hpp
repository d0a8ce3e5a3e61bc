// Incremental mapping of a scan sequence and its products -- what `shine map --mode incremental`
// and `shine forgetting` run: scans one by one -> IncrementalMapper (with progress) -> map.vdb,
// surface.vdb, mesh.ply (write_map_products, as in batch mode), and with
// incremental.mesh_every = K a mesh of the map so far every K frames,
// OUT/progress/mesh_NNNNNN.ply (NNNNNN the frame just integrated), so a user can watch it grow.
//
// With config.odometry.estimate_poses the scans' own poses are ignored: each scan's pose is
// estimated on the map built so far (scan_odometry.hpp) and the scan is mapped there; the
// estimated poses are written to OUT/poses.txt (KITTI 3x4, one line per scan, skipped scans
// included) and, for a recording (scans with times), OUT/poses_tum.txt. Tracking is decoupled
// from mapping (keyframe_policy.hpp): every scan is registered, the keyframes train the map when
// they come, the other scans are deferred and, with a consolidation (consolidation_steps > 0),
// integrated untrained after the last scan, before the consolidation trains every kept scan.
#pragma once

#include <cstddef>
#include <deque>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/checkpoint.hpp"
#include "shine/mapper/incremental_mapper.hpp"
#include "shine/mapper/keyframe_policy.hpp"
#include "shine/mapper/map_sequence.hpp"
#include "shine/mapper/scan_odometry.hpp"
#include "shine/mapper/sequence_deskew.hpp"

namespace shine {

/// One mesh written during the run.
struct ProgressMesh {
    std::size_t frame = 0;  ///< index (in the sequence) of the last frame integrated
    std::filesystem::path path;
    std::size_t triangles = 0;
    double bake_seconds = 0.0;  ///< bake and mesh of the map so far
    double write_seconds = 0.0;
};

/// A sequence mapped incrementally: the mapper (NeuralSdf, per-frame stats) and the products.
struct IncrementalSequenceMap {
    std::unique_ptr<IncrementalMapper> mapper;
    MapProducts products;
    std::vector<ProgressMesh> progress_meshes;
    /// The estimated poses and per-scan records (null unless config.odometry.estimate_poses).
    std::unique_ptr<ScanOdometry> odometry;
    /// Per scan: load, preprocess, allocate, normals, sample, train, importance; bake and mesh of
    /// the final products once (progress meshes are not counted).
    StageProfile profile;
    DeskewStats deskew;  ///< what deskewing did (config.deskew, sequence_deskew.hpp)
    /// With estimated poses: which scans trained when they came, which were deferred to the
    /// catch-up after the last scan (keyframe_policy.hpp), and the counts; null otherwise.
    std::unique_ptr<KeyframePolicy> keyframes;
    /// Per scan of the sequence (with keyframes): the policy's choice (a skipped scan's:
    /// trained false, reason kRedundant).
    std::vector<KeyframeChoice> keyframe_choices;
    /// Deferred scans waiting for the catch-up (empty after the run).
    std::deque<std::size_t> deferred;
    /// keyframes.keyframe_takes_deferred_steps: the scans deferred as redundant since the last
    /// keyframe (whose steps the next keyframe takes), and the deferred scans whose steps the
    /// keyframes took.
    std::size_t steps_owed = 0;
    std::size_t deferred_steps_taken = 0;
    double catch_up_seconds = 0.0;  ///< integrating the deferred scans after the last one
    /// A continued map: the old drive's viewpoints cast (MapToContinue) and how long it took.
    std::size_t old_viewpoints = 0;
    double old_viewpoint_seconds = 0.0;
    /// Wall-clock seconds of each scan this run went through, from its load to the end of its
    /// mapping (odometry, deskew and mapping included; a resumed run's replayed scans are not).
    std::vector<double> scan_wall_seconds;
    /// The sequence index of each scan the mapper integrated, in the order it integrated them
    /// (the scans that trained when they came, then the deferred ones caught up).
    std::vector<std::size_t> mapper_scans;
    /// With pose refinement in the consolidation (refine.in_consolidation): every scan's pose in
    /// the world frame after it, the kept scans' corrected and every other scan's as it was
    /// mapped (the sequence's, or the estimated one); empty without.
    std::vector<Eigen::Isometry3d> refined_poses_world;
};

/// A saved map that a run continues (`shine map --from`; docs/continue.md).
struct MapToContinue {
    std::filesystem::path file;  ///< the map.vdb it was read from (errors, records)
    NeuralSdf* sdf = nullptr;    ///< load_neural_map's; moved into the mapper
    /// The old drive, when its folder has them: its surface (mesh.ply) and the sensor poses it
    /// was mapped from (world frame). From each pose the surface is cast in the new drive's
    /// LiDAR pattern and votes on the new scans' movers (IncrementalMapper::add_old_viewpoints).
    const TriangleMesh* surface = nullptr;
    std::vector<Eigen::Isometry3d> trajectory_world;
};

/// Range images of `surface` (any frame origin) seen from each pose of `trajectory_world` in the
/// directions of `points_sensor` (a scan of the new drive: its returns' directions), returns up
/// to max_range_m, with the map-to-sensor transforms of the map frame at `origin_world_m`.
std::vector<std::pair<Eigen::Isometry3f, RangeImage>> surface_viewpoints(
    const TriangleMesh& surface, const std::vector<Eigen::Isometry3d>& trajectory_world,
    const Eigen::Vector3d& origin_world_m, const std::vector<Eigen::Vector3f>& points_sensor,
    double max_range_m);

/// Maps every scan of `sequence` in incremental mode with `config` (finalized here) and writes the
/// products into `out_dir` (created if missing), plus the progress meshes every
/// config.incremental.mesh_every frames. Scans with per-point times are deskewed when
/// deskew_active(config.deskew, config.odometry.estimate_poses): with the sequence's poses, or
/// with the estimated motion (sequence_deskew.hpp). Progress lines are labelled "map", followed by
/// `progress_tag` when it is not empty. Throws what the steps throw (IoError, DataError naming
/// the scan, ConfigError).
///
/// With a `control` (checkpoint.hpp): after every frame it polls control->stop_requested and,
/// when that is true, writes a checkpoint and throws Interrupted (no product is written); it also
/// writes one every control->checkpoint_interval_s. With control->resume it replays the frames
/// the checkpoint had integrated (IncrementalMapper::replay_scan), restores the state and goes on
/// with the next frame; with odometry the checkpoint holds the estimated poses, so that the
/// replayed scans sit where they were mapped.
///
/// With `from` the run continues that map (IncrementalMapper::start_from: its features, frozen
/// decoder and origin, old rows held at the importance cap) and the sequence's poses must be in
/// its world frame; the products hold the old part and the new scans. Throws ConfigError for a
/// map whose settings differ from `config` (naming the file and the setting), for odometry
/// (config.odometry.estimate_poses: localise the scans in the map first, map_localizer.hpp) and
/// for a checkpoint resume (control->resume). The run writes no checkpoint.
IncrementalSequenceMap map_sequence_incremental(const MapperConfig& config,
                                                const ScanSequence& sequence,
                                                const std::filesystem::path& out_dir,
                                                const std::string& progress_tag = {},
                                                const RunControl* control = nullptr,
                                                const MapToContinue* from = nullptr);

}  // namespace shine
