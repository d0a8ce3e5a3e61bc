// `shine bench --speed`: the speed table of ShineVDB against the TSDF baseline, from one
// alternated run. Each round maps the same scans three times, in a rotating order -- the TSDF
// baseline configured as VDBFusion runs (0.1 m voxels, 0.3 m truncation, every point, no hole
// filling), ShineVDB batch and ShineVDB incremental at the configured leaf (0.2 m by default),
// and incremental without the poses (odometry; keyframe_policy.hpp) -- data without poses times
// that run alone --
// each as its own `shine` process, so that no run inherits another's caches or allocations. A
// shared, noisy machine is compared side by side: the ratios are taken within a round, then their
// median over the rounds is reported with its range.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace shine::cli {

struct SpeedStudyOptions {
    std::filesystem::path data;  ///< the sequence (already resolved)
    std::filesystem::path out;   ///< OUT: runs go to OUT/speed/<method>_<round>/
    std::string shine_args;      ///< extra arguments of every `shine map` run (-c ...)
    std::string selection_args;  ///< frame selection / pose file, for every run
    int rounds = 3;              ///< alternated rounds
    int threads = 2;             ///< worker threads of every run
    double tsdf_voxel_m = 0.1;   ///< the TSDF baseline's voxel (truncation: 3 voxels)
    /// Whether the data has poses: without, only the run without poses can be timed.
    bool data_has_poses = true;
    bool quiet = false;
};

/// One method's figures over the rounds.
struct SpeedRow {
    /// "tsdf", "batch", "incremental", "no poses" (incremental, every pose estimated)
    std::string method;
    std::vector<double> wall_seconds;      ///< whole run, measured around the process
    std::vector<double> per_scan_seconds;  ///< median per scan (TSDF: integration / scans)
    /// "no poses": the mean wall time a scan, load to end of mapping (what a sensor's rate
    /// must cover), the deferred scans' catch-up after the last scan not included.
    std::vector<double> mean_per_scan_seconds;
};

/// Runs the study, writes OUT/speed.md and OUT/speed.json and returns the rows. Throws Error
/// naming the run and its log when a run fails.
std::vector<SpeedRow> run_speed_study(const SpeedStudyOptions& options);

/// The Markdown table of `rows`: medians with ranges, and the ratios to the TSDF taken round by
/// round.
std::string format_speed_table(const std::vector<SpeedRow>& rows);

}  // namespace shine::cli
