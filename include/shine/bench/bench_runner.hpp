// The memory/accuracy study behind `shine bench`: ShineVDB (batch mode, and with
// BenchConfig::modes incremental mode too) and the TSDF baseline (VDBFusion's algorithm) on the
// same scans at a list of resolutions, each evaluated against one reference.
//
// At resolution s, ShineVDB runs with leaf size s (the rest of its configuration unchanged) and
// the TSDF with voxel size s and truncation trunc_voxels * s (VDBFusion's 3 voxels; its other
// defaults unchanged). Both get the same Scan objects and the same preprocessing (ShineVDB's), so
// their inputs are identical; the scans are read from disk once for the whole study when they fit
// in the cache budget, otherwise once per resolution (each scan then goes to both mappers before
// the next is read).
//
// Incremental mode runs after them, as `shine map --mode incremental` runs
// (map_sequence_incremental: the scans one by one, the consolidation, the products), reading its
// scans from disk again.
//
// Per resolution the products are written as the single-method commands write them:
//   OUT/shinevdb_<s>/map.vdb, surface.vdb, mesh.ply               (as `shine map`)
//   OUT/tsdf_<s>/tsdf.vdb, mesh.ply                                (as `shine tsdf`)
//   OUT/shinevdb_incremental_<s>/map.vdb, surface.vdb, mesh.ply   (as `shine map --mode
//                                                                   incremental`)
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "shine/bench/bench_row.hpp"
#include "shine/eval/heldout_ranges.hpp"
#include "shine/eval/mesh_metrics.hpp"
#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/mapper_config.hpp"
#include "shine/tsdf/tsdf_mapper.hpp"

namespace shine {

/// The modes ShineVDB runs in during a study (at least one).
struct BenchModes {
    bool batch = true;
    bool incremental = false;
};

/// Settings of a study; every member has a default.
struct BenchConfig {
    std::vector<double> sizes_m = {0.1, 0.2, 0.5, 1.0};  ///< resolutions, metres
    BenchModes modes;
    MapperConfig shine;     ///< ShineVDB's configuration; the leaf size is set per resolution
    TsdfMapperConfig tsdf;  ///< TSDF configuration; voxel size and truncation set per resolution,
                            ///< preprocessing replaced by shine.preprocess
                            ///< except its voxel_downsample_m
    double trunc_voxels = 3.0;  ///< TSDF truncation in voxels (VDBFusion: 0.3 m at 0.1 m)
    EvalConfig eval;            ///< evaluation protocol (`shine eval`'s defaults)
    /// Scans (indices into the sequence, ascending) that neither method maps; each mesh is
    /// scored on them with the held-out yardstick. Empty: every scan is mapped.
    std::vector<std::size_t> heldout_frames;
    /// The yardstick's settings; run_bench_size() takes its range limits from ShineVDB's
    /// preprocessing, as `shine map --holdout-every` does.
    HeldoutConfig heldout;
    /// Scans are kept in memory for the whole study when their files total at most this many
    /// bytes (the bundled street: 90 MB).
    std::size_t scan_cache_bytes = std::size_t(2) << 30;
};

/// Parses a comma-separated list of resolutions ("0.1,0.2,0.5,1.0"), sorted ascending. Throws
/// ConfigError naming --sizes-m and the value if the list is empty, has an empty entry, an entry
/// that is not a number, a non-positive or non-finite size, or a size given twice.
std::vector<double> parse_sizes_m(const std::string& text);

/// Parses a comma-separated list of ShineVDB modes ("batch", "incremental", "batch,incremental"
/// in any order). Throws ConfigError naming --modes and the value if the list is empty, has an
/// empty entry, an unknown mode or a mode given twice.
BenchModes parse_modes(const std::string& text);

/// The modes as --modes takes them: "batch", "incremental" or "batch,incremental".
std::string format_modes(const BenchModes& modes);

/// ShineVDB's configuration at `size_m` (leaf size), finalized.
MapperConfig shine_config_at(const BenchConfig& config, double size_m);

/// The TSDF configuration at `size_m`: voxel size, truncation trunc_voxels * size_m, and
/// ShineVDB's preprocessing. Validated.
TsdfMapperConfig tsdf_config_at(const BenchConfig& config, double size_m);

/// Output directory of one run: OUT/<method>_<size> (e.g. out/tsdf_0.2).
std::filesystem::path bench_run_dir(const std::filesystem::path& out_dir, BenchMethod method,
                                    double size_m);

/// The scans of a study: all read into memory at construction (with a progress line) when their
/// files total at most `cache_budget_bytes`, else read from disk on each request.
class BenchScans {
  public:
    BenchScans(ScanSequence sequence, std::size_t cache_budget_bytes);

    std::size_t size() const { return sequence_.size(); }
    const ScanSequence& sequence() const { return sequence_; }
    bool cached() const { return !cache_.empty() || sequence_.size() == 0; }
    /// Scan i: the cached one, or read from disk into `storage` and returned. Throws what
    /// ScanSequence::load throws (IoError / DataError naming the file).
    const Scan& scan(std::size_t i, Scan& storage) const;

  private:
    ScanSequence sequence_;
    std::vector<Scan> cache_;
};

/// Runs ShineVDB in config.modes and the TSDF baseline at `size_m` on `scans` (but
/// config.heldout_frames), writes their products under `out_dir` (see the file comment),
/// evaluates every mesh against `reference` when it is not null and scores them on the held-out
/// scans when there are any. Returns the rows in the order ShineVDB batch (if run), TSDF,
/// ShineVDB incremental (if run). Progress lines name the stage and the size.
std::vector<BenchRow> run_bench_size(const BenchConfig& config, double size_m,
                                     const BenchScans& scans, const TriangleMesh* reference,
                                     const std::filesystem::path& out_dir);

/// Mesh metrics in the study's units.
BenchMetrics to_bench_metrics(const MeshMetrics& metrics);

/// Pooled held-out figures in the study's units.
BenchHeldout to_bench_heldout(const RangeErrorStats& stats);

}  // namespace shine
