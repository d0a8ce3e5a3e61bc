// Incremental mapping of a scan sequence and its products -- what `shine map --mode incremental`
// and `shine forgetting` run: scans one by one -> IncrementalMapper (with progress) -> map.vdb,
// surface.vdb, mesh.ply (write_map_products, as in batch mode), and with
// incremental.mesh_every = K a mesh of the map so far every K frames,
// OUT/progress/mesh_NNNNNN.ply (NNNNNN the frame just integrated), so a user can watch it grow.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/checkpoint.hpp"
#include "shine/mapper/incremental_mapper.hpp"
#include "shine/mapper/map_sequence.hpp"

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
    /// Per scan: load, preprocess, allocate, normals, sample, train, importance; bake and mesh of
    /// the final products once (progress meshes are not counted).
    StageProfile profile;
};

/// Maps every scan of `sequence` in incremental mode with `config` (finalized here) and writes the
/// products into `out_dir` (created if missing), plus the progress meshes every
/// config.incremental.mesh_every frames. Progress lines are labelled "map", followed by
/// `progress_tag` when it is not empty. Throws what the steps throw (IoError, DataError naming
/// the scan, ConfigError).
///
/// With a `control` (checkpoint.hpp): after every frame it polls control->stop_requested and,
/// when that is true, writes a checkpoint and throws Interrupted (no product is written); it also
/// writes one every control->checkpoint_interval_s. With control->resume it replays the frames
/// the checkpoint had integrated (IncrementalMapper::replay_scan), restores the state and goes on
/// with the next frame.
IncrementalSequenceMap map_sequence_incremental(const MapperConfig& config,
                                                const ScanSequence& sequence,
                                                const std::filesystem::path& out_dir,
                                                const std::string& progress_tag = {},
                                                const RunControl* control = nullptr);

}  // namespace shine
