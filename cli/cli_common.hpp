// Helpers shared by the subcommands: thread limits, timing, memory, default data location.
#pragma once

#include <tbb/global_control.h>

#include <CLI/CLI.hpp>
#include <chrono>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "shine/core/stopwatch.hpp"
#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/preprocess.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/sequence_deskew.hpp"

namespace shine::cli {

/// Limits TBB to `threads` (0 = all hardware threads) for the lifetime of the returned object.
std::unique_ptr<tbb::global_control> limit_threads(int threads);

/// Peak resident set size of this process in bytes.
std::size_t peak_rss_bytes();

/// Where the bundled example street lives (simulated on first use).
std::filesystem::path bundled_example_dir();

/// The sequence directory a subcommand works on: `data`, or when it is empty the bundled example
/// street, simulated there on first use (with a progress line unless `quiet`).
std::filesystem::path resolve_data_dir(const std::string& data, bool quiet);

/// The reference mesh to evaluate against: `ref_path` if given, else `data`/gt_mesh.ply when it
/// exists and `no_eval` is false, else empty (no evaluation). Throws IoError if `ref_path` names
/// a file that does not exist.
std::filesystem::path resolve_reference(const std::filesystem::path& data,
                                        const std::string& ref_path, bool no_eval);

/// The options that select scans of a sequence: --first-frame, --last-frame, --frame-step, --poses
/// (for a recording the frames are its messages in time order).
void add_scan_selection_options(CLI::App* cmd, int& first_frame, int& last_frame, int& frame_step,
                                std::string& poses_path);

/// --topic: the PointCloud2 topic of a recording (needed when it has several).
void add_topic_option(CLI::App* cmd, std::string& topic);

/// The evaluation options: --ref (reference mesh) and --no-eval.
void add_evaluation_options(CLI::App* cmd, std::string& ref_path, bool& no_eval);

/// The scans a run maps and those it holds out (`--holdout-every N`): indices into the selected
/// sequence; all scans are mapped when N is 0.
struct HoldoutSplit {
    std::vector<std::size_t> mapped;
    std::vector<std::size_t> heldout;
};

/// Splits `selected` for --holdout-every `every` (0: none held out). Throws ConfigError when N
/// holds out no scan.
HoldoutSplit split_holdout(const ScanSequence& selected, int every);

/// Scores `mesh_path` on the held-out scans of `selected` with the run's range limits, prints
/// the table and stores it in json[key] (and its seconds in json["seconds"][key]).
/// With `deskew`, each held-out scan is deskewed first with the poses of `selected` around it
/// (deskew_with_sequence_poses: the poses only, never the scan's own points), as mapping deskews
/// the mapped scans. With `mesh` (what mesh_path holds, kept in memory), the file is not read.
void score_heldout(const std::filesystem::path& mesh_path, const ScanSequence& selected,
                   const HoldoutSplit& split, int every, const PreprocessConfig& preprocess,
                   nlohmann::json& json, const std::string& key = "heldout",
                   const DeskewConfig* deskew = nullptr, const TriangleMesh* mesh = nullptr);

/// `selected` timed from the azimuth where config says so (sequence_with_sweep_times: by the
/// sweep test under deskew.azimuth_times auto); prints the verdict unless `quiet`.
ScanSequence with_sweep_times_if_skewed(const ScanSequence& selected, const DeskewConfig& config,
                                        bool quiet);

/// Poses for every scan of a run that estimated the poses of its mapped scans
/// (`mapped_world_sensor`, one per split.mapped) and holds some out: a mapped scan keeps its
/// estimate; a held-out scan h is placed relative to the nearest mapped scan a before it by the
/// data's own relative motion, T(h) = T_est(a) T_data(a)^-1 T_data(h), so that the drift of the
/// estimate against the data's poses is not counted as map error.
std::vector<Eigen::Isometry3d> heldout_poses_local_to_estimate(
    const ScanSequence& selected, const HoldoutSplit& split,
    const std::vector<Eigen::Isometry3d>& mapped_world_sensor);

/// --holdout-every N: map without every N-th selected scan and score the result on those.
void add_holdout_option(CLI::App* cmd, int& holdout_every);

/// A simulated sequence with noisy poses (`shine simulate --pose-noise-m`) keeps the true poses
/// beside them in this file; `shine map` scores its map also in their frame.
inline constexpr const char* kTruePosesFile = "poses_true.txt";

// seconds_since(start): shine/core/stopwatch.hpp.

}  // namespace shine::cli
