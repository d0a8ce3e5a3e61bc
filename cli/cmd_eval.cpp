// `shine eval`: the quality of a predicted mesh, against a reference mesh (DESIGN.md,
// "Evaluation protocol": accuracy, completion, Chamfer-L1 in cm; precision, completion ratio,
// F-score in %) or, on real data without one, against scans the map never saw (held-out rays
// cast into the mesh: hit ratio, range errors; eval/heldout_ranges.hpp).
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "command_registry.hpp"
#include "mapped_run.hpp"
#include "shine/core/error.hpp"
#include "shine/eval/ghost_area.hpp"
#include "shine/eval/heldout_ranges.hpp"
#include "shine/eval/mesh_metrics.hpp"
#include "shine/eval/metrics_report.hpp"
#include "shine/eval/tiled_evaluation.hpp"
#include "shine/io/mover_tracks.hpp"
#include "shine/io/ply.hpp"

namespace shine::cli {
namespace {

struct EvalOptions {
    std::string pred_path;
    std::string ref_path;
    EvalConfig config;
    bool json = false;
    std::string movers_path;  ///< simulation.json with movers: also the ghost area
    double tile_m = 0.0;      ///< > 0: score tile by tile (a city)
    // Held-out evaluation.
    std::string heldout_dir;
    std::string frames;
    int holdout_every = 0;
    std::string poses_path;
    std::string run_dir;  ///< --run: score as that `shine map` run did (mapped_run.hpp)
    HeldoutConfig heldout;
};

int run_heldout(const EvalOptions& options) {
    if (options.frames.empty() == (options.holdout_every == 0)) {
        throw ConfigError(
            "--heldout needs the frames to score: --frames LIST (e.g. 2,5,8 or 2:52:3) or "
            "--holdout-every N (the scans `shine map --holdout-every N` left out)");
    }
    ScanSequenceOptions seq_options;
    seq_options.poses_path = options.poses_path;
    const ScanSequence sequence = ScanSequence::open(options.heldout_dir, seq_options);
    const std::vector<std::size_t> frames =
        options.frames.empty() ? holdout_frames(sequence.size(), options.holdout_every)
                               : parse_frame_list(options.frames, sequence.size());
    HeldoutConfig config = options.heldout;
    config.threshold_m = options.config.threshold_m;
    // With --run, the scans placed and deskewed as that run placed and deskewed its held-out
    // scans (the poses of the scans around each, never its own points).
    std::optional<MappedRun> run;
    if (!options.run_dir.empty()) run = read_mapped_run(options.run_dir, sequence);
    const ScanSequence scored = run ? run->apply(sequence) : sequence;
    DeskewStats deskew_stats;
    ScanPreparation prepare;
    if (run && run->deskew) {
        prepare = [&](std::size_t frame, Scan& scan) {
            deskew_with_sequence_poses(scan, scored, frame, *run->deskew, deskew_stats);
        };
    }
    const HeldoutReport report =
        evaluate_heldout(read_ply_mesh(options.pred_path), scored, frames, config, prepare);
    if (options.json) {
        nlohmann::json json = nlohmann::json::parse(heldout_to_json(report));
        if (run) {
            json["run"] = {{"dir", options.run_dir},
                           {"placement", run->describe()},
                           {"scans_deskewed", deskew_stats.scans_deskewed}};
        }
        std::printf("%s\n", json.dump().c_str());
    } else {
        std::printf("pred     %s\nheld out %s\n", options.pred_path.c_str(),
                    options.heldout_dir.c_str());
        if (run) std::printf("scored   %s\n", run->describe().c_str());
        std::printf("%s", format_heldout(report).c_str());
    }
    return 0;
}

int run_tiled(const EvalOptions& options, const TriangleMesh& pred, const TriangleMesh& ref,
              const EvalConfig& eval, const MoverTracks& movers) {
    TiledEvalConfig config;
    config.eval = eval;
    config.tile_m = options.tile_m;
    config.show_progress = !options.json;
    const bool with_movers = !options.movers_path.empty();
    const TiledEvaluation result =
        evaluate_meshes_tiled(pred, ref, config, with_movers ? &movers : nullptr);
    if (options.json) {
        nlohmann::ordered_json json =
            nlohmann::ordered_json::parse(metrics_to_json(result.metrics));
        if (with_movers)
            json["ghost"] = nlohmann::ordered_json::parse(ghost_metrics_to_json(result.ghost));
        json["tiles"] = {{"tile_m", options.tile_m},
                         {"scored", result.tiles_scored},
                         {"unscored_pred_area_m2", result.unscored_pred_area_m2}};
        std::printf("%s\n", json.dump().c_str());
        return 0;
    }
    std::printf("pred   %s\nref    %s\n%s%s%s", options.pred_path.c_str(), options.ref_path.c_str(),
                with_movers ? ("movers " + options.movers_path + "\n").c_str() : "",
                format_metrics(result.metrics).c_str(),
                with_movers ? format_ghost_metrics(result.ghost).c_str() : "");
    std::printf(
        "tiles             %zu of %.0f m scored (each sampled at its own density, the "
        "lowest above); %.1f m^2 predicted where no reference surface was observed, "
        "not scored\n",
        result.tiles_scored, options.tile_m, result.unscored_pred_area_m2);
    return 0;
}

int run_eval(const EvalOptions& options) {
    if (options.ref_path.empty() == options.heldout_dir.empty()) {
        throw ConfigError(
            "give either --ref MESH (a reference surface) or --heldout SEQUENCE (scans the map "
            "never saw), not both or neither");
    }
    if (!options.heldout_dir.empty()) {
        if (!options.movers_path.empty()) {
            throw ConfigError(
                "--movers measures ghosts against a reference mesh: use it with "
                "--ref, not --heldout");
        }
        if (options.tile_m > 0.0) {
            throw ConfigError("--tile-m scores a mesh against a reference mesh: use it with --ref");
        }
        return run_heldout(options);
    }
    if (!options.run_dir.empty()) {
        throw ConfigError(
            "--run places held-out scans as a mapping run did: use it with --heldout");
    }
    // read_ply_mesh throws IoError naming the file for missing or corrupt input.
    const TriangleMesh ref = read_ply_mesh(options.ref_path);
    const TriangleMesh pred = read_ply_mesh(options.pred_path);
    // Below 0.1 m the protocol's other lengths follow the threshold (mesh_metrics.hpp).
    EvalConfig config = eval_config_for_threshold(options.config.threshold_m);
    config.seed = options.config.seed;
    // The movers are read first: a bad simulation.json fails before the slow part.
    const MoverTracks movers =
        options.movers_path.empty() ? MoverTracks{} : read_mover_tracks(options.movers_path);
    if (options.tile_m > 0.0) return run_tiled(options, pred, ref, config, movers);
    const MeshMetrics metrics = evaluate_meshes(pred, ref, config);
    if (options.movers_path.empty()) {
        if (options.json) {
            std::printf("%s\n", metrics_to_json(metrics).c_str());
        } else {
            std::printf("pred  %s\nref   %s\n%s", options.pred_path.c_str(),
                        options.ref_path.c_str(), format_metrics(metrics).c_str());
        }
        return 0;
    }
    GhostConfig ghost_config;
    ghost_config.eval = config;
    const GhostMetrics ghost = measure_ghost_area(pred, ref, movers, ghost_config);
    if (options.json) {
        nlohmann::ordered_json json = nlohmann::ordered_json::parse(metrics_to_json(metrics));
        json["ghost"] = nlohmann::ordered_json::parse(ghost_metrics_to_json(ghost));
        std::printf("%s\n", json.dump().c_str());
    } else {
        std::printf("pred   %s\nref    %s\nmovers %s\n%s%s", options.pred_path.c_str(),
                    options.ref_path.c_str(), options.movers_path.c_str(),
                    format_metrics(metrics).c_str(), format_ghost_metrics(ghost).c_str());
    }
    return 0;
}

const RegisterCommand kEvalCommand(50, [](CLI::App& app, Action& action) {
    auto options = std::make_shared<EvalOptions>();
    CLI::App* cmd = app.add_subcommand(
        "eval",
        "Score a mesh against a reference mesh (accuracy, completion, Chamfer-L1 in cm; "
        "precision, completion ratio, F-score in %; completion counts only reference faces "
        "marked observed), or against held-out scans: their rays cast into the mesh (hit ratio, "
        "median and mean range error, share within the threshold; misses fail)");
    cmd->add_option("--pred", options->pred_path, "predicted mesh (PLY)")->required();
    cmd->add_option("--ref", options->ref_path,
                    "reference mesh (PLY; optional uchar face property 'observed')");
    cmd->add_option("--threshold-m", options->config.threshold_m,
                    "distance threshold of precision and completion ratio, and of a good held-out "
                    "range, m (0.2 for noisy data; below 0.1 the sampling density and 2 cm "
                    "downsampling shrink with it, e.g. 0.001 for an object)")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    cmd->add_option("--seed", options->config.seed, "seed of the surface sampling")
        ->capture_default_str();
    cmd->add_option("--tile-m", options->tile_m,
                    "with --ref: score tile by tile (square columns of this edge, m), each at the "
                    "protocol's density, and combine by area: for scenes too large for one "
                    "sampling (a city; docs/city_scale.md)")
        ->check(CLI::PositiveNumber);
    cmd->add_option("--heldout", options->heldout_dir,
                    "sequence whose scans score the mesh (any layout `shine map` reads)");
    cmd->add_option("--frames", options->frames,
                    "with --heldout: the scans to score, e.g. 2,5,8 or 2:52:3 (from 0)");
    cmd->add_option("--holdout-every", options->holdout_every,
                    "with --heldout: score scans N-1, 2N-1, ... (those `shine map "
                    "--holdout-every N` left out)")
        ->check(CLI::Range(2, 1000000));
    cmd->add_option("--poses", options->poses_path,
                    "with --heldout: pose file (default: found in the sequence)");
    cmd->add_option("--run", options->run_dir,
                    "with --heldout: the output folder of the `shine map` run the mesh came from: "
                    "score the scans as it scored its held-out scans (at its refined poses, "
                    "deskewed as it deskewed; the figures of its stats.json)")
        ->excludes("--poses");
    cmd->add_option("--min-range-m", options->heldout.min_range_m,
                    "with --heldout: rays measured closer are not scored")
        ->capture_default_str();
    cmd->add_option("--max-range-m", options->heldout.max_range_m,
                    "with --heldout: rays measured farther are not scored")
        ->capture_default_str();
    cmd->add_option("--movers", options->movers_path,
                    "with --ref: simulation.json of `shine simulate --movers N`; also report the "
                    "ghost area (predicted surface off the static reference and inside a volume "
                    "a mover swept) and its share of the observed reference (docs/movers.md)");
    cmd->add_flag("--json", options->json, "print one JSON object (metres, ratios in [0, 1])");
    cmd->callback([options, &action] { action = [options] { return run_eval(*options); }; });
});

}  // namespace
}  // namespace shine::cli
