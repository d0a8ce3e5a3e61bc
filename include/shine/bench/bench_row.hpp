// One result of the memory/accuracy study (`shine bench`): one method (ShineVDB in one mode, or
// the TSDF baseline) at one resolution.
#pragma once

#include <cstddef>
#include <optional>
#include <string>

namespace shine {

/// The methods the study compares (the values keep their order: kShineVdb is batch mode, as in
/// files written before incremental mode joined the study).
enum class BenchMethod {
    kShineVdb,             ///< the neural map in batch mode (leaf size = resolution)
    kTsdf,                 ///< TSDF fusion with VDBFusion's algorithm (voxel size = resolution)
    kShineVdbIncremental,  ///< the neural map in incremental mode (leaf size = resolution)
};

/// "shinevdb", "tsdf" or "shinevdb_incremental": the name used in file names, the CSV and the
/// JSON.
std::string method_name(BenchMethod method);
/// "ShineVDB", "TSDF" or "ShineVDB incremental": the name used in tables and plots.
std::string method_label(BenchMethod method);
/// Inverse of method_name(); throws DataError naming `name` for anything else.
BenchMethod parse_method_name(const std::string& name);

/// The resolution as used in directory names and tables: shortest round-trip form with at least
/// one decimal ("0.1", "0.25", "1.0").
std::string format_size_m(double size_m);

/// Mesh quality against the reference (EvalConfig's protocol): metres and ratios in [0, 1].
struct BenchMetrics {
    double accuracy_m = 0.0;
    double completion_m = 0.0;
    double chamfer_l1_m = 0.0;
    double completion_ratio = 0.0;
    double precision = 0.0;
    double fscore = 0.0;
};

/// The held-out yardstick (eval/heldout_ranges.hpp) on the scans the run did not map: their rays
/// cast into the run's mesh. Ratios in [0, 1], errors in metres over the rays that hit.
struct BenchHeldout {
    std::size_t rays = 0;
    double hit_ratio = 0.0;
    double within_ratio = 0.0;  ///< rays within the threshold (a miss is a failure)
    double median_abs_error_m = 0.0;
    double mean_abs_error_m = 0.0;
};

/// Memory, time and accuracy of one method at one resolution.
struct BenchRow {
    BenchMethod method = BenchMethod::kShineVdb;
    double size_m = 0.0;     ///< leaf size (ShineVDB) or voxel size (TSDF)
    std::size_t frames = 0;  ///< scans mapped
    /// ShineVDB optimisation steps of the map (0 for TSDF): with a warm start from pose
    /// refinement's first phase, its steps up to the warm start and the steps after it.
    std::size_t iterations = 0;
    std::size_t map_bytes = 0;   ///< ShineVDB: features + OpenVDB structure + decoder
                                 ///< (NeuralSdf::memory_bytes); TSDF: memUsage() of TSDF + weight
    std::size_t file_bytes = 0;  ///< map.vdb or tsdf.vdb on disk
    /// Wall time from the scans in memory to the mesh on disk (reading scans and eval excluded):
    /// batch and TSDF as the sum of their stages (they take the scans in turns), incremental
    /// mode measured around its whole run.
    double seconds = 0.0;
    double seconds_per_frame = 0.0;       ///< per-frame mapping time, as in the stats.json files
    std::optional<BenchMetrics> metrics;  ///< empty when there is no reference mesh
    std::optional<BenchHeldout> heldout;  ///< empty when no scan was held out
};

}  // namespace shine
