// `shine eval-poses EST REF`: how far an estimated trajectory is from a reference one (docs/
// odometry.md): the absolute trajectory error after an SE(3) (or Sim(3)) alignment, Umeyama
// 1991, and the KITTI benchmark's relative error per segment length, Geiger et al. 2012
// (definitions in odometry/trajectory_error.hpp).
//
// KITTI pose files have no times: their poses are paired line by line, so the files must have
// the same number. TUM files are paired by nearest timestamp within --max-time-diff-s.
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "command_registry.hpp"
#include "pose_file_format.hpp"
#include "shine/core/error.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/tum.hpp"
#include "shine/odometry/pose_association.hpp"
#include "shine/odometry/trajectory_error.hpp"

namespace shine::cli {
namespace {

struct EvalPosesOptions {
    std::string estimate_path;
    std::string reference_path;
    std::string format = "auto";
    std::string align = "se3";
    double max_time_diff_s = 0.01;
    int step_frames = 10;
    bool json = false;
};

PoseFileFormat format_of(const std::string& path, const std::string& option) {
    if (option == "kitti") return PoseFileFormat::kKitti;
    if (option == "tum") return PoseFileFormat::kTum;
    return detect_pose_file_format(path, "pose file", "; give --format if the file is one of them");
}

/// The two trajectories paired pose by pose, with a note on how they were paired.
struct PairedTrajectories {
    std::vector<Eigen::Isometry3d> estimate, reference;
    PoseFileFormat format = PoseFileFormat::kKitti;
    std::size_t estimate_count = 0, reference_count = 0;
};

PairedTrajectories read_paired(const EvalPosesOptions& options) {
    const PoseFileFormat est_format = format_of(options.estimate_path, options.format);
    const PoseFileFormat ref_format = format_of(options.reference_path, options.format);
    if (est_format != ref_format) {
        throw DataError("'" + options.estimate_path + "' is a " + to_string(est_format) +
                        " pose file but '" + options.reference_path + "' a " +
                        to_string(ref_format) +
                        " one: KITTI files pair poses by line, TUM files by time; convert one of "
                        "them");
    }
    PairedTrajectories out;
    out.format = est_format;
    if (est_format == PoseFileFormat::kKitti) {
        out.estimate = read_kitti_poses(options.estimate_path);
        out.reference = read_kitti_poses(options.reference_path);
        out.estimate_count = out.estimate.size();
        out.reference_count = out.reference.size();
        if (out.estimate.size() != out.reference.size()) {
            throw DataError("'" + options.estimate_path + "' has " +
                            std::to_string(out.estimate.size()) + " poses but '" +
                            options.reference_path + "' has " +
                            std::to_string(out.reference.size()) +
                            ": KITTI pose files are paired line by line, so both must hold one "
                            "pose per scan of the same sequence");
        }
        return out;
    }
    const std::vector<StampedPose> est = read_tum_poses(options.estimate_path);
    const std::vector<StampedPose> ref = read_tum_poses(options.reference_path);
    out.estimate_count = est.size();
    out.reference_count = ref.size();
    const PosePairs pairs = associate_by_time(est, ref, options.max_time_diff_s,
                                              options.estimate_path, options.reference_path);
    if (pairs.size() < 3) {
        throw DataError("only " + std::to_string(pairs.size()) + " of the " +
                        std::to_string(est.size()) + " poses of '" + options.estimate_path +
                        "' have a pose of '" + options.reference_path + "' within " +
                        std::to_string(options.max_time_diff_s) +
                        " s; at least 3 are needed (are both in the same clock? raise "
                        "--max-time-diff-s)");
    }
    for (const auto& [i, j] : pairs) {
        out.estimate.push_back(est[i].T_world_sensor);
        out.reference.push_back(ref[j].T_world_sensor);
    }
    return out;
}

int run_eval_poses(const EvalPosesOptions& options) {
    const TrajectoryAlignment alignment = parse_trajectory_alignment(options.align, "--align");
    const PairedTrajectories paired = read_paired(options);
    const AbsoluteTrajectoryError ate =
        absolute_trajectory_error(paired.estimate, paired.reference, alignment);
    RelativePoseErrorConfig rpe_config;
    rpe_config.step_frames = options.step_frames;
    const RelativePoseError rpe =
        relative_pose_error(paired.estimate, paired.reference, rpe_config);

    if (options.json) {
        nlohmann::json j;
        j["estimate"] = options.estimate_path;
        j["reference"] = options.reference_path;
        j["format"] = to_string(paired.format);
        j["estimate_poses"] = paired.estimate_count;
        j["reference_poses"] = paired.reference_count;
        j["paired_poses"] = paired.estimate.size();
        j["ate"] = {{"alignment", to_string(ate.alignment)},
                    {"rmse_m", ate.rmse_m},
                    {"mean_m", ate.mean_m},
                    {"median_m", ate.median_m},
                    {"max_m", ate.max_m},
                    {"scale", ate.estimate_to_reference.scale}};
        nlohmann::json rows = nlohmann::json::array();
        for (const auto& row : rpe.per_length) {
            rows.push_back({{"length_m", row.length_m},
                            {"segments", row.num_segments},
                            {"translation_percent", row.translation_percent},
                            {"rotation_deg_per_100m", row.rotation_deg_per_100m}});
        }
        j["rpe"] = {{"path_length_m", rpe.path_length_m},
                    {"kitti_lengths", rpe.kitti_lengths},
                    {"step_frames", options.step_frames},
                    {"segments", rpe.num_segments},
                    {"translation_percent", rpe.translation_percent},
                    {"rotation_deg_per_100m", rpe.rotation_deg_per_100m},
                    {"per_length", rows}};
        std::printf("%s\n", j.dump(2).c_str());
        return 0;
    }
    std::printf("estimate   %s (%zu poses)\nreference  %s (%zu poses)\n",
                options.estimate_path.c_str(), paired.estimate_count,
                options.reference_path.c_str(), paired.reference_count);
    if (paired.format == PoseFileFormat::kTum) {
        std::printf("paired     %zu poses by timestamp (within %g s)\n", paired.estimate.size(),
                    options.max_time_diff_s);
    } else {
        std::printf("paired     %zu poses by line (KITTI)\n", paired.estimate.size());
    }
    std::printf("\nabsolute trajectory error (alignment %s", to_string(ate.alignment));
    if (alignment == TrajectoryAlignment::kSim3) {
        std::printf(", scale %.6f", ate.estimate_to_reference.scale);
    }
    std::printf(")\n  RMSE     %.4f m\n  mean     %.4f m\n  median   %.4f m\n  max      %.4f m\n",
                ate.rmse_m, ate.mean_m, ate.median_m, ate.max_m);
    std::printf("\nrelative error over %.1f m of reference path (%s, a segment every %d frames)\n",
                rpe.path_length_m,
                rpe.kitti_lengths ? "KITTI lengths 100..800 m that fit"
                                  : "path shorter than 100 m: 10..80 % of its length",
                options.step_frames);
    std::printf("  %10s  %8s  %14s  %17s\n", "length m", "segments", "translation %",
                "rotation deg/100m");
    for (const auto& row : rpe.per_length) {
        if (row.num_segments == 0) {
            std::printf("  %10.1f  %8zu  %14s  %17s\n", row.length_m, row.num_segments, "-", "-");
            continue;
        }
        std::printf("  %10.1f  %8zu  %14.4f  %17.4f\n", row.length_m, row.num_segments,
                    row.translation_percent, row.rotation_deg_per_100m);
    }
    std::printf("  %10s  %8zu  %14.4f  %17.4f\n", "all", rpe.num_segments, rpe.translation_percent,
                rpe.rotation_deg_per_100m);
    return 0;
}

const RegisterCommand kEvalPosesCommand(51, [](CLI::App& app, Action& action) {
    auto options = std::make_shared<EvalPosesOptions>();
    CLI::App* cmd = app.add_subcommand(
        "eval-poses",
        "Score an estimated trajectory against a reference: absolute trajectory error after "
        "alignment (RMSE, mean, median, max, m) and the KITTI relative error (translation %, "
        "rotation deg/100 m per segment length)");
    cmd->add_option("EST", options->estimate_path, "estimated poses (KITTI or TUM file)")
        ->required();
    cmd->add_option("REF", options->reference_path, "reference poses (same format)")->required();
    cmd->add_option("--format", options->format,
                    "pose file format: kitti (12 numbers a line, paired by line), tum (time tx ty "
                    "tz qx qy qz qw, paired by time) or auto (from the first line)")
        ->check(CLI::IsMember({"kitti", "tum", "auto"}))
        ->capture_default_str();
    cmd->add_option("--align", options->align,
                    "alignment before the absolute error: se3, sim3 (with scale) or none")
        ->check(CLI::IsMember({"se3", "sim3", "none"}))
        ->capture_default_str();
    cmd->add_option("--max-time-diff-s", options->max_time_diff_s,
                    "TUM: largest time difference of a pose pair, s")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    cmd->add_option("--step-frames", options->step_frames,
                    "relative error: a segment starts every N frames (KITTI devkit: 10)")
        ->check(CLI::Range(1, 1000000))
        ->capture_default_str();
    cmd->add_flag("--json", options->json, "print one JSON object");
    cmd->callback([options, &action] { action = [options] { return run_eval_poses(*options); }; });
});

}  // namespace
}  // namespace shine::cli
