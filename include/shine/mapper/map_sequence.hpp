// Batch mapping of a scan sequence and its products -- the steps `shine map` and `shine bench`
// share: scans -> BatchMapper (with progress) -> training -> map.vdb -> surface.vdb (baked level
// set) -> mesh.ply, with the seconds each step took.
//
//   map_sequence()               = add every scan + train_with_progress() + write_map_products()
//   train_with_progress()        the training loop behind a Progress line
//   write_map_products()         save map.vdb, bake and save surface.vdb, mesh and save mesh.ply
//
// Callers that feed the scans themselves (the benchmark passes each scan to the TSDF baseline
// too) use the last two directly. Evaluation is left to the caller (module eval).
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "shine/bake/level_set_bake.hpp"
#include "shine/colour/reflectance_voxels.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/batch_mapper.hpp"
#include "shine/mapper/checkpoint.hpp"
#include "shine/mapper/mapper_config.hpp"
#include "shine/mapper/pose_refinement.hpp"
#include "shine/mapper/sequence_deskew.hpp"
#include "shine/mapper/stage_profile.hpp"
#include "shine/mapper/written_surface.hpp"
#include "shine/mesh/level_set_mesh.hpp"
#include "shine/model/neural_sdf.hpp"

namespace shine {

/// What write_map_products() made, and the wall-clock seconds of each step.
struct MapProducts {
    BakeStats bake;
    std::size_t surface_mem_bytes = 0;  ///< memUsage() of the baked level set
    MeshFileStats mesh;                 ///< mesh.ply (read it back to evaluate it)
    /// Seconds of each stage. The saving runs beside the baking and the writing of surface.vdb
    /// beside the meshing, so their sum is more than the wall time they took.
    double save_seconds = 0.0;  ///< writing map.vdb
    double bake_seconds = 0.0;  ///< baking and writing surface.vdb
    double mesh_seconds = 0.0;  ///< meshing and writing mesh.ply
    /// With write_map_products(..., keep_surface): the level set and mesh as written.
    std::optional<WrittenSurface> written;
};

/// A mapped sequence: the mapper (which owns the NeuralSdf, its rays and MappingStats) and the
/// products written to disk.
struct SequenceMap {
    std::unique_ptr<BatchMapper> mapper;
    MapProducts products;
    StageProfile profile;  ///< per scan: load, preprocess, allocate; the rest once per run
    DeskewStats deskew;    ///< what deskewing did (config.deskew, sequence_deskew.hpp)
    /// With pose refinement (config.refine.rounds > 0): each scan's refined pose (world frame),
    /// the rounds' figures and the seconds of the first phase (load, train, rounds); empty / 0
    /// without.
    std::vector<Eigen::Isometry3d> refined_poses_world;
    std::vector<PoseRefinementRound> refinement;
    double refine_seconds = 0.0;
    /// How refinement changed consecutive scans' relative poses (decides the warm start).
    RelativePoseChange relative_pose_change;
    /// With refine.warm_start: the corners whose features the map took from the first phase's,
    /// and the step its training started at (the steps before it count as done).
    std::size_t warm_start_corners = 0;
    int warm_start_step = 0;
    /// Scans with intensity: their points' intensities as the map placed them, in the map frame,
    /// in voxels of the baked level set's size (surface_appearance.hpp); empty without.
    std::optional<ReflectanceVoxels> reflectance;
};

/// The bake and mesh stages of `products` in profile form.
StageSeconds product_stages(const MapProducts& products);

/// Trains `mapper` behind a Progress line labelled `label` with the running BCE; `iterations` is
/// the step count the mapper will run (its config's batch_iterations()), for the progress bar.
/// With `stop` (polled after every step) training may pause early: returns BatchMapper::train()'s
/// result.
bool train_with_progress(BatchMapper& mapper, int iterations, const std::string& label = "train",
                         const std::function<bool()>& stop = {});

/// Writes the products of a trained map into `out_dir` (which must exist): `map.vdb` (the neural
/// map with `config` as YAML), `surface.vdb` (baked with config.bake) and `mesh.ply` (meshed with
/// config.mesh, region by region: write_level_set_mesh). Every file is written atomically. Peak
/// memory beyond the map is the level set's; the mesh is never held whole, unless `keep_surface`
/// asks for the level set and the mesh in products.written (for a step that reads them next).
/// Throws IoError naming the file on failure.
MapProducts write_map_products(const NeuralSdf& sdf, const MapperConfig& config,
                               const std::filesystem::path& out_dir, bool keep_surface = false);

/// Maps every scan of `sequence` in batch mode with `config` (finalized here) and writes the
/// products into `out_dir` (created if missing). With config.refine.rounds > 0 (the default) the
/// scans' poses are first refined on a map of their own (pose_refinement.hpp: a first phase with
/// the dynamic-point filter off) and the map is then made at the refined poses. Scans with
/// per-point times are deskewed with the sequence's poses when deskew_active(config.deskew,
/// config.odometry.estimate_poses) (sequence_deskew.hpp). Progress lines are labelled "load" and
/// "train", followed by `progress_tag` when it is not empty. Throws what the steps throw (IoError,
/// DataError naming the scan, ConfigError).
///
/// With a `control` (checkpoint.hpp): after every scan and every optimisation step it polls
/// control->stop_requested and, when that is true, writes a checkpoint and throws Interrupted
/// (no product is written); it also writes one every control->checkpoint_interval_s. With
/// control->resume it first loads every scan again, restores the checkpoint's training state and
/// continues. The checkpoint file is left in place (the caller removes it once it has what it
/// needs).
///
/// The level set and the mesh stay in memory (products.written) when `keep_surface` is set or
/// the scans carried intensity: the surface's colour and reflectance, which read them, come next.
SequenceMap map_sequence(const MapperConfig& config, const ScanSequence& sequence,
                         const std::filesystem::path& out_dir, const std::string& progress_tag = {},
                         const RunControl* control = nullptr, bool keep_surface = false);

/// Every scan of `selected` placed with pose refinement's corrections (interpolate_corrections):
/// the scans `mapped` (indices into `selected`, ascending) at `refined_mapped`, each other scan at
/// `given_world[i]` corrected as the mapped scans around it were, by frame number. `given_world`
/// holds the poses the map started from, one per scan of `selected`. Throws DataError for
/// mismatched counts.
std::vector<Eigen::Isometry3d> poses_with_corrections(
    const ScanSequence& selected, const std::vector<std::size_t>& mapped,
    const std::vector<Eigen::Isometry3d>& given_world,
    const std::vector<Eigen::Isometry3d>& refined_mapped);

}  // namespace shine
