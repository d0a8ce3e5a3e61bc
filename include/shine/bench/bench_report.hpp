// Reports of the memory/accuracy study: CSV and JSON files (with readers, so results can be
// re-plotted or compared later), terminal tables, the ShineVDB/TSDF ratios per resolution, and the
// study's checks computed from the rows (ratios and checks compare ShineVDB's batch-mode rows with
// the TSDF; incremental-mode rows appear in the tables, files and the held-out comparison):
//   (a) ShineVDB's map is smaller than the TSDF map at every resolution;
//   (b) the smallest ShineVDB map whose Chamfer-L1 is at least as good as the best TSDF result of
//       the study takes at most 1/4 of that TSDF map's bytes;
//   (c) completion ratio of ShineVDB vs TSDF at 0.1 m and 0.2 m.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "shine/bench/bench_row.hpp"

namespace shine {

/// Check (b)'s bound: ShineVDB map bytes / TSDF map bytes.
constexpr double kMaxMemoryRatioAtTsdfQuality = 0.25;

/// ShineVDB (batch mode) against TSDF at one resolution where both ran.
struct BenchRatio {
    double size_m = 0.0;
    double memory_ratio = 0.0;                ///< ShineVDB map bytes / TSDF map bytes
    std::optional<double> chamfer_ratio;      ///< ShineVDB Chamfer-L1 / TSDF Chamfer-L1
    std::optional<double> fscore_difference;  ///< ShineVDB F-score - TSDF F-score (ratio units)
    /// With held-out scans: ShineVDB - TSDF share of rays within the threshold and hit ratio
    /// (ratio units), ShineVDB / TSDF median range error.
    std::optional<double> heldout_within_difference;
    std::optional<double> heldout_hit_difference;
    std::optional<double> heldout_median_ratio;
};

/// Completion ratio of both methods at one resolution (check (c)).
struct CompletionComparison {
    double size_m = 0.0;
    double shine_completion_ratio = 0.0;
    double tsdf_completion_ratio = 0.0;
};

/// The study's checks, computed from the rows.
struct BenchChecks {
    /// (a): over the resolutions where both methods ran (none: not applicable).
    bool smaller_applicable = false;
    bool shine_smaller_at_every_size = false;
    std::vector<double> sizes_where_shine_not_smaller;

    /// (b): needs evaluated TSDF rows. best_tsdf is the TSDF row with the lowest Chamfer-L1 (ties:
    /// the smaller map); smallest_good_shine the smallest ShineVDB map with Chamfer-L1 <= it.
    std::optional<BenchRow> best_tsdf;
    std::optional<BenchRow> smallest_good_shine;  ///< empty: no ShineVDB run is good enough
    std::optional<double> memory_ratio;           ///< smallest_good_shine / best_tsdf map bytes
    bool memory_at_tsdf_quality_pass = false;     ///< memory_ratio <= 1/4

    /// (c): at 0.1 m and 0.2 m when both methods were evaluated there.
    std::vector<CompletionComparison> completion;
};

/// Context of a study, stored in bench.json.
struct BenchInfo {
    std::string data;            ///< sequence directory
    std::string reference;       ///< reference mesh (empty: not evaluated)
    std::string config;          ///< -c file (empty: defaults)
    int threads = 0;             ///< 0: all cores
    int iterations = -1;         ///< ShineVDB training steps; -1: automatic per leaf size
    bool half_features = false;  ///< ShineVDB features stored as float16
    double trunc_voxels = 3.0;   ///< TSDF truncation in voxels
    int holdout_every = 0;       ///< every N-th scan held out and scored (0: none)
    std::vector<std::string> modes = {"batch"};  ///< ShineVDB's modes: batch, incremental
    double heldout_threshold_m = 0.1;
};

/// Ratios per resolution (sorted by size) where both methods ran.
std::vector<BenchRatio> compute_ratios(const std::vector<BenchRow>& rows);

/// The checks (a), (b), (c) above.
BenchChecks compute_checks(const std::vector<BenchRow>& rows);

/// CSV with a header line; metres, bytes, seconds, ratios in [0, 1]; empty metric (held-out)
/// fields when a row was not evaluated (held nothing out). Numbers are written in their shortest
/// exact form, so rows_from_csv() gives back the same values.
std::string rows_to_csv(const std::vector<BenchRow>& rows);

/// Parses rows_to_csv() output (also that of versions without the held-out columns). Throws
/// DataError naming `source` and the line on a bad header,
/// a wrong field count, or a value that is not a number.
std::vector<BenchRow> rows_from_csv(const std::string& text, const std::string& source = "CSV");

/// bench.json: info, rows (metrics as an "eval" object or null, held-out figures as a "heldout"
/// object or null), ratios and checks.
std::string bench_to_json(const std::vector<BenchRow>& rows, const BenchInfo& info);

/// The rows of bench_to_json() output. Throws DataError naming `source` on malformed JSON.
std::vector<BenchRow> rows_from_json(const std::string& text, const std::string& source = "JSON");

/// Terminal table of all rows: MB, seconds, cm and %.
std::string format_rows_table(const std::vector<BenchRow>& rows);

/// Terminal table of compute_ratios(): memory ratio, Chamfer ratio, F-score difference.
std::string format_ratios_table(const std::vector<BenchRatio>& ratios);

/// Terminal table of the held-out figures (and wall seconds and map memory) of the rows that have
/// them, per size the TSDF, ShineVDB batch and ShineVDB incremental rows, then each ShineVDB
/// mode's differences to the TSDF ("S - T" batch, "I - T" incremental; seconds and memory as
/// ratios); empty when no row has any.
std::string format_heldout_table(const std::vector<BenchRow>& rows);

/// The checks in words, with the numbers they rest on.
std::string format_checks(const BenchChecks& checks);

/// bench.md: the rows, the ratios and the checks as Markdown tables and text, ready to paste into
/// docs/benchmark.md when the study is re-run.
std::string bench_to_markdown(const std::vector<BenchRow>& rows, const BenchInfo& info);

}  // namespace shine
