#include "shine/bench/bench_runner.hpp"

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <memory>
#include <optional>
#include <sstream>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/core/stopwatch.hpp"
#include "shine/io/ply.hpp"
#include "shine/mapper/incremental_sequence.hpp"
#include "shine/mapper/map_sequence.hpp"
#include "shine/mapper/sequence_deskew.hpp"
#include "shine/mapper/sweep_test.hpp"
#include "shine/model/map_file.hpp"
#include "shine/tsdf/tsdf_file.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace {

std::string trim(const std::string& s) {
    const auto begin = s.find_first_not_of(" \t");
    if (begin == std::string::npos) return {};
    return s.substr(begin, s.find_last_not_of(" \t") - begin + 1);
}

/// The trimmed entries of the comma-separated list `text`; an empty entry (a trailing comma
/// included) is a ConfigError "`where`: empty entry; separate `what` by single commas".
std::vector<std::string> list_entries(const std::string& text, const std::string& where,
                                      const char* what) {
    std::vector<std::string> entries;
    std::istringstream in(text + ",");  // the sentinel makes a trailing comma an empty entry
    std::string item;
    while (std::getline(in, item, ',')) {
        std::string value = trim(item);
        if (value.empty()) {
            throw ConfigError(where + ": empty entry; separate " + what + " by single commas");
        }
        entries.push_back(std::move(value));
    }
    return entries;
}

}  // namespace

std::vector<double> parse_sizes_m(const std::string& text) {
    const std::string where = "--sizes-m '" + text + "'";
    if (trim(text).empty()) {
        throw ConfigError(where +
                          ": the list is empty; give sizes in metres, e.g. 0.1,0.2,0.5,1.0");
    }
    std::vector<double> sizes;
    for (const std::string& value : list_entries(text, where, "sizes")) {
        double size = 0.0;
        const auto result = std::from_chars(value.data(), value.data() + value.size(), size);
        if (result.ec != std::errc() || result.ptr != value.data() + value.size()) {
            throw ConfigError(where + ": '" + value + "' is not a number");
        }
        if (!std::isfinite(size) || !(size > 0.0)) {
            throw ConfigError(where + ": " + value + " is not a positive size in metres");
        }
        if (std::find(sizes.begin(), sizes.end(), size) != sizes.end()) {
            throw ConfigError(where + ": " + value + " is given twice");
        }
        sizes.push_back(size);
    }
    std::sort(sizes.begin(), sizes.end());
    return sizes;
}

BenchModes parse_modes(const std::string& text) {
    const std::string where = "--modes '" + text + "'";
    if (trim(text).empty()) {
        throw ConfigError(where + ": the list is empty; give batch, incremental or both, e.g. " +
                          "batch,incremental");
    }
    BenchModes modes;
    modes.batch = false;
    for (const std::string& value : list_entries(text, where, "modes")) {
        bool* mode = value == "batch"         ? &modes.batch
                     : value == "incremental" ? &modes.incremental
                                              : nullptr;
        if (!mode) {
            throw ConfigError(where + ": unknown mode '" + value +
                              "' (expected batch or incremental)");
        }
        if (*mode) throw ConfigError(where + ": " + value + " is given twice");
        *mode = true;
    }
    return modes;
}

std::string format_modes(const BenchModes& modes) {
    if (modes.batch && modes.incremental) return "batch,incremental";
    return modes.incremental ? "incremental" : "batch";
}

MapperConfig shine_config_at(const BenchConfig& config, double size_m) {
    MapperConfig c = config.shine;
    c.octree.leaf_size_m = size_m;
    c.finalize();
    return c;
}

TsdfMapperConfig tsdf_config_at(const BenchConfig& config, double size_m) {
    TsdfMapperConfig c = config.tsdf;
    // The same scans, cropped alike; each method keeps its own voxel thinning (the TSDF fuses
    // every 5 cm point, the neural map trains on a 0.2 m grid: mapper_config.hpp).
    const double tsdf_voxel_downsample_m = c.preprocess.voxel_downsample_m;
    c.preprocess = config.shine.preprocess;
    c.preprocess.voxel_downsample_m = tsdf_voxel_downsample_m;
    c.tsdf.voxel_size_m = size_m;
    c.tsdf.trunc_m = config.trunc_voxels * size_m;
    c.validate();
    return c;
}

fs::path bench_run_dir(const fs::path& out_dir, BenchMethod method, double size_m) {
    return out_dir / (method_name(method) + "_" + format_size_m(size_m));
}

BenchHeldout to_bench_heldout(const RangeErrorStats& stats) {
    return {stats.rays, stats.hit_ratio(), stats.within_ratio(), stats.median_abs_error_m,
            stats.mean_abs_error_m};
}

BenchMetrics to_bench_metrics(const MeshMetrics& m) {
    return {m.accuracy_m,       m.completion_m, m.chamfer_l1_m,
            m.completion_ratio, m.precision,    m.fscore};
}

BenchScans::BenchScans(ScanSequence sequence, std::size_t cache_budget_bytes)
    : sequence_(std::move(sequence)) {
    std::size_t file_bytes = 0;
    for (std::size_t i = 0; i < sequence_.size(); ++i) {
        std::error_code ec;
        const auto bytes = fs::file_size(sequence_.scan_path(i), ec);
        if (!ec) file_bytes += static_cast<std::size_t>(bytes);
    }
    if (file_bytes > cache_budget_bytes) return;
    cache_.reserve(sequence_.size());
    Progress progress("read", sequence_.size());
    for (std::size_t i = 0; i < sequence_.size(); ++i) {
        cache_.push_back(sequence_.load(i));
        progress.update(i + 1);
    }
    progress.finish(std::to_string(sequence_.size()) + " scans in memory");
}

const Scan& BenchScans::scan(std::size_t i, Scan& storage) const {
    if (!cache_.empty()) return cache_.at(i);
    storage = sequence_.load(i);
    return storage;
}

std::vector<BenchRow> run_bench_size(const BenchConfig& config, double size_m,
                                     const BenchScans& scans, const TriangleMesh* reference,
                                     const fs::path& out_dir) {
    if (!config.modes.batch && !config.modes.incremental) {
        throw ConfigError("run_bench_size: no ShineVDB mode to run (BenchConfig::modes)");
    }
    const std::string tag = format_size_m(size_m) + " m";
    const MapperConfig shine_config = shine_config_at(config, size_m);
    const TsdfMapperConfig tsdf_config = tsdf_config_at(config, size_m);

    BenchRow shine_row;
    shine_row.method = BenchMethod::kShineVdb;
    shine_row.size_m = size_m;
    BenchRow tsdf_row;
    tsdf_row.method = BenchMethod::kTsdf;
    tsdf_row.size_m = size_m;

    HeldoutConfig heldout_config = config.heldout;
    heldout_config.min_range_m = shine_config.preprocess.min_range_m;
    heldout_config.max_range_m = shine_config.preprocess.max_range_m;
    const std::vector<std::size_t>& heldout = config.heldout_frames;
    const auto score_heldout = [&](const TriangleMesh& mesh, const ScanSequence& scored,
                                   const ScanPreparation& prepare) {
        return to_bench_heldout(
            evaluate_heldout(mesh, scored, heldout, heldout_config, prepare).total);
    };
    const auto is_heldout = [&](std::size_t i) {
        return std::binary_search(heldout.begin(), heldout.end(), i);
    };

    auto tsdf = std::make_unique<TsdfMapper>(tsdf_config);
    {
        Progress progress("load " + tag, scans.size());
        Scan storage;
        for (std::size_t i = 0; i < scans.size(); ++i) {
            if (is_heldout(i)) continue;
            tsdf->add_scan(scans.scan(i, storage));
            progress.update(i + 1);
        }
        progress.finish(std::to_string(tsdf->volume().active_voxels()) + " voxels");
    }

    // The TSDF is finished first, so its grids are freed before ShineVDB maps.
    {
        Progress progress("tsdf " + tag, 3);
        progress.update(0, "mesh");
        auto t0 = std::chrono::steady_clock::now();
        const TriangleMesh mesh = tsdf->extract_mesh();
        const double mesh_seconds = seconds_since(t0);
        progress.update(1, "save");
        const fs::path dir = bench_run_dir(out_dir, BenchMethod::kTsdf, size_m);
        ensure_directory(dir);
        t0 = std::chrono::steady_clock::now();
        write_tsdf_volume(dir / "tsdf.vdb", tsdf->volume());
        write_ply_mesh(dir / "mesh.ply", mesh);
        const double save_seconds = seconds_since(t0);

        const TsdfMappingStats& stats = tsdf->stats();
        const double mapping_seconds = stats.preprocess_seconds + stats.integrate_seconds;
        tsdf_row.frames = stats.frames;
        tsdf_row.map_bytes = tsdf->volume().memory_bytes();
        tsdf_row.file_bytes = file_bytes(dir / "tsdf.vdb");
        tsdf_row.seconds = mapping_seconds + mesh_seconds + save_seconds;
        tsdf_row.seconds_per_frame = stats.frames ? mapping_seconds / stats.frames : 0.0;
        tsdf.reset();
        if (reference) {
            progress.update(2, "eval");
            tsdf_row.metrics = to_bench_metrics(evaluate_meshes(mesh, *reference, config.eval));
        }
        if (!heldout.empty()) {
            progress.update(2, "held-out scans");
            tsdf_row.heldout = score_heldout(mesh, scans.sequence(), {});
        }
        progress.finish(std::to_string(mesh.triangles.size()) + " triangles");
    }

    // The mesh of a ShineVDB run, read back from its directory, evaluated and scored.
    const auto evaluate_shine = [&](BenchRow& row, const fs::path& dir, Progress& progress,
                                    std::size_t step, const ScanSequence& scored,
                                    const ScanPreparation& prepare) {
        if (!reference && heldout.empty()) return;
        const TriangleMesh mesh = read_ply_mesh(dir / "mesh.ply");
        if (reference) {
            progress.update(step, "eval");
            row.metrics = to_bench_metrics(evaluate_meshes(mesh, *reference, config.eval));
        }
        if (!heldout.empty()) {
            progress.update(step, "held-out scans");
            row.heldout = score_heldout(mesh, scored, prepare);
        }
    };

    std::vector<BenchRow> rows;
    std::vector<std::size_t> mapped;
    for (std::size_t i = 0; i < scans.size(); ++i) {
        if (!is_heldout(i)) mapped.push_back(i);
    }
    // A ShineVDB run's figures: its stats, its map, its map.vdb in `dir` and its wall time.
    const auto fill_shine_row = [](BenchRow& row, const MappingStats& stats, const NeuralSdf& sdf,
                                   const fs::path& dir, double wall_seconds) {
        const double mapping_seconds = stats.load_seconds + stats.allocate_seconds +
                                       stats.normals_seconds + stats.train_seconds;
        row.frames = stats.frames;
        row.iterations = stats.iterations;
        row.map_bytes = sdf.memory_bytes();
        row.file_bytes = file_bytes(dir / "map.vdb");
        row.seconds = wall_seconds;
        row.seconds_per_frame = stats.frames ? mapping_seconds / stats.frames : 0.0;
    };
    // The scans' read time is not counted, as the TSDF gets its scans read.
    const auto read_seconds = [](const StageProfile& profile) {
        double seconds = 0.0;
        for (const StageSeconds& frame : profile.frames) seconds += frame[Stage::kLoad];
        return seconds;
    };
    // The scans as `shine map` reads them where it refines given poses (batch mode, incremental
    // mode's consolidation): timed from the azimuth where the sweep test finds them skewed. The
    // test runs once for both modes.
    std::optional<ScanSequence> timed;
    const auto selection_for = [&](bool refining) {
        const ScanSequence& given = scans.sequence();
        if (!sweep_times_apply(shine_config.deskew, refining, shine_config.odometry.estimate_poses,
                               given)) {
            return given;
        }
        if (!timed) timed = sequence_with_sweep_times(given, shine_config.deskew);
        return *timed;
    };
    // Each scan placed as `shine map` scores it: a mapped one at its refined pose, a held-out one
    // with the corrections of the mapped scans around it (never with its own points).
    const auto placed = [&](const ScanSequence& selected,
                            const std::vector<Eigen::Isometry3d>& refined_mapped) {
        if (refined_mapped.empty()) return selected;
        std::vector<Eigen::Isometry3d> given(selected.size());
        for (std::size_t i = 0; i < selected.size(); ++i) given[i] = selected.pose(i);
        return selected.with_poses(poses_with_corrections(selected, mapped, given, refined_mapped));
    };
    // Held-out scans deskewed as the mapped ones were, with the poses they are scored at.
    const auto deskewing = [&](const ScanSequence& scored, DeskewStats& stats) {
        ScanPreparation prepare;
        if (deskew_active(shine_config.deskew, shine_config.odometry.estimate_poses,
                          scored.has_sweep_times())) {
            prepare = [&scored, &stats, &shine_config](std::size_t frame, Scan& scan) {
                deskew_with_sequence_poses(scan, scored, frame, shine_config.deskew, stats);
            };
        }
        return prepare;
    };
    if (config.modes.batch) {
        // As `shine map` maps in batch mode by default: the poses refined with the map, the
        // held-out scans placed and deskewed as above.
        const ScanSequence selected = selection_for(shine_config.refine.rounds > 0);
        const fs::path dir = bench_run_dir(out_dir, BenchMethod::kShineVdb, size_m);
        const auto t0 = std::chrono::steady_clock::now();
        SequenceMap run = map_sequence(shine_config, selected.subset(mapped), dir, "batch " + tag);
        const double wall_seconds = seconds_since(t0) - read_seconds(run.profile);
        const ScanSequence scored = placed(selected, run.refined_poses_world);
        DeskewStats deskew_stats;
        const ScanPreparation prepare = deskewing(scored, deskew_stats);

        BenchRow row = shine_row;
        fill_shine_row(row, run.mapper->stats(), run.mapper->sdf(), dir, wall_seconds);
        // A warm-started map (pose_refinement.hpp) took its first steps from the first phase.
        if (run.warm_start_corners > 0) row.iterations += run.warm_start_step;
        const std::size_t triangles = run.products.mesh.triangles;
        run.mapper.reset();  // its memory goes to the evaluation and to incremental mode
        Progress progress("shine " + tag, 1);
        evaluate_shine(row, dir, progress, 0, scored, prepare);
        progress.finish(std::to_string(triangles) + " triangles");
        rows.push_back(row);
    }
    rows.push_back(tsdf_row);

    if (config.modes.incremental) {
        // As `shine map --mode incremental` maps the scans it is given: read one by one, mapped,
        // consolidated (the kept scans' poses refined there), products written; the held-out
        // scans placed and deskewed as above.
        const ScanSequence selected = selection_for(shine_config.refines_in_consolidation());
        const fs::path dir = bench_run_dir(out_dir, BenchMethod::kShineVdbIncremental, size_m);
        const auto t0 = std::chrono::steady_clock::now();
        IncrementalSequenceMap run = map_sequence_incremental(shine_config, selected.subset(mapped),
                                                              dir, "incremental " + tag);
        const double wall_seconds = seconds_since(t0) - read_seconds(run.profile);
        const ScanSequence scored = placed(selected, run.refined_poses_world);
        DeskewStats deskew_stats;
        const ScanPreparation prepare = deskewing(scored, deskew_stats);

        BenchRow row;
        row.method = BenchMethod::kShineVdbIncremental;
        row.size_m = size_m;
        fill_shine_row(row, run.mapper->stats(), run.mapper->sdf(), dir, wall_seconds);
        const std::size_t triangles = run.products.mesh.triangles;
        run.mapper.reset();
        Progress progress("incremental " + tag, 1);
        evaluate_shine(row, dir, progress, 0, scored, prepare);
        progress.finish(std::to_string(triangles) + " triangles");
        rows.push_back(row);
    }
    return rows;
}

}  // namespace shine
