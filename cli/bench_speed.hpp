// `shine bench --speed`: the speed table of ShineVDB against the TSDF baseline, from one
// alternated run. Each round maps the same scans three times, in a rotating order -- the TSDF
// baseline configured as VDBFusion runs (0.1 m voxels, 0.3 m truncation, every point, no hole
// filling), ShineVDB batch and ShineVDB incremental at the configured leaf (0.2 m by default) --
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
    bool quiet = false;
};

/// One method's figures over the rounds.
struct SpeedRow {
    std::string method;                    ///< "tsdf", "batch", "incremental"
    std::vector<double> wall_seconds;      ///< whole run, measured around the process
    std::vector<double> per_scan_seconds;  ///< median per scan (TSDF: integration / scans)
};

/// Runs the study, writes OUT/speed.md and OUT/speed.json and returns the rows. Throws Error
/// naming the run and its log when a run fails.
std::vector<SpeedRow> run_speed_study(const SpeedStudyOptions& options);

/// The Markdown table of `rows`: medians with ranges, and the ratios to the TSDF taken round by
/// round.
std::string format_speed_table(const std::vector<SpeedRow>& rows);

}  // namespace shine::cli
