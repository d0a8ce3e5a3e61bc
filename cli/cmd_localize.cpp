// `shine localize MAP DATA -o OUT`: the pose of every scan of DATA in a saved map, which is never
// changed (mapper/map_localizer.hpp, docs/localize.md). Writes OUT/poses.txt (KITTI),
// OUT/poses_tum.txt and OUT/stats.json; DATA's own poses, if any, only score the result. For a map
// made at refined poses the poses are written in the frame of the poses the map started from
// (geometry/pose_frame_correction.hpp), and in the map's own frame as OUT/poses_map.txt.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "command_registry.hpp"
#include "pose_file_format.hpp"
#include "saved_map.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/median.hpp"
#include "shine/core/progress.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/tum.hpp"
#include "shine/mapper/map_localizer.hpp"
#include "shine/mapper/sequence_deskew.hpp"
#include "shine/model/map_file.hpp"
#include "shine/odometry/trajectory_error.hpp"

namespace shine::cli {
namespace {
namespace fs = std::filesystem;

struct LocalizeOptions {
    std::string map;
    std::string data;
    std::string out;
    std::string initial_pose_path;
    LocalizeConfig config;
    int threads = 0;
    int first_frame = 0, last_frame = -1, frame_step = 1;
    std::string poses_path;
    std::string topic;
    bool quiet = false;
    bool map_frame = false;  ///< poses.txt in the map's frame even when it has poses_given.txt
};

/// The first pose of a KITTI (12 numbers a line) or TUM (8) pose file.
Eigen::Isometry3d first_pose_of(const std::string& path) {
    if (detect_pose_file_format(path, "initial pose file") == PoseFileFormat::kKitti) {
        return read_kitti_poses(path).front();
    }
    return read_tum_poses(path).front().T_world_sensor;
}

nlohmann::json stage_json(const LocalizeStageSeconds& s) {
    return {{"selection", s.selection},   {"starts", s.starts}, {"tracking", s.tracking},
            {"recovery", s.recovery},     {"search", s.search}, {"sdf_queries", s.sdf_queries},
            {"acceptance", s.acceptance}, {"icp", s.icp}};
}

/// Per stage, the median over the scans in milliseconds: over all scans, over the tracked ones
/// and over the others (recovered, searched or bridged), so that the two paths read apart.
nlohmann::json stage_medians_ms(const std::vector<LocalizeRecord>& records,
                                const std::vector<double>& load_seconds) {
    nlohmann::json out;
    const char* groups[] = {"all", "tracked", "not_tracked"};
    for (int g = 0; g < 3; ++g) {
        std::vector<std::vector<double>> values(10);
        for (std::size_t i = 0; i < records.size(); ++i) {
            const LocalizeRecord& r = records[i];
            const bool tracked = r.source == LocalizeSource::kTracked;
            if ((g == 1 && !tracked) || (g == 2 && tracked)) continue;
            const LocalizeStageSeconds& s = r.stage_seconds;
            const double v[10] = {load_seconds[i], s.selection, s.starts,      s.tracking,
                                  s.recovery,      s.search,    s.sdf_queries, s.acceptance,
                                  s.icp,           r.seconds};
            for (int k = 0; k < 10; ++k) values[k].push_back(1000.0 * v[k]);
        }
        if (values[0].empty()) continue;
        const char* names[] = {"load",   "selection",   "starts",     "tracking", "recovery",
                               "search", "sdf_queries", "acceptance", "icp",      "total"};
        nlohmann::json group;
        group["scans"] = values[0].size();
        for (int k = 0; k < 10; ++k) group[names[k]] = median(values[k]);
        out[groups[g]] = group;
    }
    return out;
}

double rotation_deg(const Eigen::Matrix3d& R) {
    return Eigen::AngleAxisd(R).angle() * 180.0 / M_PI;
}

int run_localize(const LocalizeOptions& opt) {
    Progress::set_globally_enabled(!opt.quiet);
    auto thread_limit = limit_threads(opt.threads);
    validate(opt.config);
    const fs::path map_file = saved_map_file(opt.map, "map");
    const fs::path out(opt.out);

    ScanSequenceOptions seq_options;
    seq_options.first_frame = opt.first_frame;
    seq_options.last_frame = opt.last_frame;
    seq_options.frame_step = opt.frame_step;
    seq_options.poses_path = opt.poses_path;
    seq_options.topic = opt.topic;
    seq_options.poses = PoseFileUse::kIfPresent;
    const ScanSequence sequence = ScanSequence::open(opt.data, seq_options);
    std::optional<Eigen::Isometry3d> initial;
    if (!opt.initial_pose_path.empty()) initial = first_pose_of(opt.initial_pose_path);

    const LoadedMap loaded = load_neural_map(map_file);
    std::string trajectory_source;
    const std::vector<Eigen::Isometry3d> trajectory =
        saved_map_trajectory(map_file, trajectory_source);
    MapLocalizer localizer(loaded.sdf, opt.config, trajectory);
    std::string frame_note;
    std::optional<PoseFrameCorrection> frame;
    if (!opt.map_frame) frame = saved_map_frame_correction(map_file, frame_note);
    if (!frame_note.empty()) std::printf("%s\n", frame_note.c_str());
    // --initial-pose is in the given poses' frame, as the poses written.
    if (initial) localizer.set_initial_pose(frame ? frame->to_map(*initial) : *initial);
    if (!opt.quiet) {
        std::printf("map %s: %zu feature corners, leaf %.2f m, %zu surface points\n",
                    map_file.c_str(), loaded.sdf.octree.num_corners(),
                    loaded.sdf.octree.config().leaf_size_m, localizer.surface_points());
        if (initial) {
            std::printf("first scan from the pose in %s\n", opt.initial_pose_path.c_str());
        } else if (!trajectory.empty()) {
            std::printf("first scan: searched around %zu places of the map's trajectory (%s)\n",
                        localizer.places().size(), trajectory_source.c_str());
        } else {
            std::printf(
                "first scan: searched around the world origin only (no --initial-pose and no "
                "trajectory beside the map)\n");
        }
    }

    ensure_directory(out);
    std::size_t failures_in_a_row = 0;
    std::vector<double> load_seconds;
    {
        Progress progress("localize", sequence.size());
        for (std::size_t i = 0; i < sequence.size(); ++i) {
            const auto load_start = std::chrono::steady_clock::now();
            const Scan scan = sequence.load(i);
            load_seconds.push_back(seconds_since(load_start));
            const LocalizeRecord& r = localizer.localize(scan.points_sensor);
            if (!r.localized) {
                if (!opt.quiet && failures_in_a_row == 0) {
                    std::printf(
                        "\nscan %zu (%s): not localised (%.0f %% of %llu points on the map's "
                        "surface), bridged by the constant-velocity prediction\n",
                        i, scan.source.filename().c_str(), 100.0 * r.inlier_ratio,
                        static_cast<unsigned long long>(r.points));
                }
                ++failures_in_a_row;
            } else {
                if (!opt.quiet && failures_in_a_row > 0) {
                    std::printf("\nscan %zu: localised again (%s) after %zu scans not localised\n",
                                i, to_string(r.source), failures_in_a_row);
                }
                failures_in_a_row = 0;
            }
            char detail[96];
            std::snprintf(detail, sizeof(detail), "%.0f ms, %.0f %% inliers, %s",
                          1000.0 * r.seconds, 100.0 * r.inlier_ratio, to_string(r.source));
            progress.update(i + 1, detail);
        }
        progress.finish();
    }

    const std::vector<LocalizeRecord>& records = localizer.records();
    std::vector<Eigen::Isometry3d> poses;
    std::vector<StampedPose> stamped(records.size());
    std::vector<double> seconds;
    std::size_t localized = 0;
    nlohmann::json per_scan = nlohmann::json::array();
    nlohmann::json sources = {
        {"tracked", 0}, {"recovered", 0}, {"global-search", 0}, {"prediction", 0}};
    const double scan_period_s = DeskewConfig{}.scan_period_s;
    std::vector<Eigen::Isometry3d> poses_map;  // in the map's own frame
    for (std::size_t i = 0; i < records.size(); ++i) {
        const LocalizeRecord& r = records[i];
        poses_map.push_back(r.T_world_sensor);
        poses.push_back(frame ? frame->to_given(r.T_world_sensor) : r.T_world_sensor);
        stamped[i].timestamp_s = sequence.from_recording()
                                     ? sequence.stamp_s(i)
                                     : sequence.frame_number(i) * scan_period_s;
        stamped[i].T_world_sensor = poses.back();
        seconds.push_back(r.seconds);
        localized += r.localized ? 1 : 0;
        sources[to_string(r.source)] = sources[to_string(r.source)].get<int>() + 1;
        per_scan.push_back({{"scan", sequence.scan_path(i).filename().string()},
                            {"localized", r.localized},
                            {"source", to_string(r.source)},
                            {"points", r.points},
                            {"valid_points", r.valid_points},
                            {"inlier_ratio", r.inlier_ratio},
                            {"residual_m", r.residual_m},
                            {"condition_number", r.condition_number},
                            {"status", to_string(r.status)},
                            {"iterations", r.iterations},
                            {"candidates", r.candidates},
                            {"start_motion_scale", r.start_motion_scale},
                            {"start_yaw_deg", r.start_yaw_deg},
                            {"start_score", r.start_score},
                            {"prediction_score", r.prediction_score},
                            {"seconds", r.seconds},
                            {"load_seconds", load_seconds[i]},
                            {"stage_seconds", stage_json(r.stage_seconds)}});
    }
    const double median_s = median(seconds);
    nlohmann::json json;
    json["map"] = map_file.string();
    json["data"] = opt.data;
    json["threads"] = opt.threads;
    json["initial_pose"] = opt.initial_pose_path;
    json["trajectory"] = trajectory_source;
    char frame_text[192];
    std::snprintf(frame_text, sizeof(frame_text),
                  "given: the poses the map started from (poses_given.txt beside it; corrections "
                  "blended over %.1f m); poses_map.txt holds them in the map's frame",
                  PoseFrameCorrection::kDefaultSigmaM);
    json["frame"] = frame ? std::string(frame_text) : std::string("the map's");
    json["localize"] = {{"scans", records.size()},
                        {"localized", localized},
                        {"sources", sources},
                        {"median_seconds_per_scan", median_s},
                        {"max_seconds_per_scan", *std::max_element(seconds.begin(), seconds.end())},
                        {"stage_medians_ms", stage_medians_ms(records, load_seconds)},
                        {"per_scan", per_scan}};

    std::printf(
        "localised %zu of %zu scans (%d tracked, %d recovered by ICP against the surface, %d after "
        "a "
        "search of the map; %d bridged by the prediction); median %.1f ms a scan\n",
        localized, records.size(), sources["tracked"].get<int>(), sources["recovered"].get<int>(),
        sources["global-search"].get<int>(), sources["prediction"].get<int>(), 1000.0 * median_s);

    if (sequence.has_poses()) {
        // DATA's poses score the result, in the map's world frame as they are (no alignment)
        // and after an SE(3) alignment (drift-free figures when the frames differ).
        std::vector<Eigen::Isometry3d> reference;
        std::vector<double> translation_m, rotation_deg_error;
        for (std::size_t i = 0; i < records.size(); ++i) {
            reference.push_back(sequence.pose(i));
            const Eigen::Isometry3d error = sequence.pose(i).inverse() * poses[i];
            translation_m.push_back(error.translation().norm());
            rotation_deg_error.push_back(rotation_deg(error.linear()));
        }
        nlohmann::json errors;
        errors["median_translation_m"] = median(translation_m);
        errors["median_rotation_deg"] = median(rotation_deg_error);
        errors["max_translation_m"] = *std::max_element(translation_m.begin(), translation_m.end());
        std::printf("against DATA's poses: median error %.2f cm and %.3f deg (max %.2f cm)",
                    100.0 * median(translation_m), median(rotation_deg_error),
                    100.0 * errors["max_translation_m"].get<double>());
        if (records.size() >= 3) {
            const AbsoluteTrajectoryError ate =
                absolute_trajectory_error(poses, reference, TrajectoryAlignment::kSe3);
            errors["ate_se3_rmse_m"] = ate.rmse_m;
            std::printf(", ATE %.2f cm (SE(3)-aligned RMSE)", 100.0 * ate.rmse_m);
            try {
                const RelativePoseError rpe = relative_pose_error(poses, reference);
                errors["rpe_translation_percent"] = rpe.translation_percent;
                errors["rpe_rotation_deg_per_100m"] = rpe.rotation_deg_per_100m;
                std::printf(", RPE %.3f %%", rpe.translation_percent);
            } catch (const DataError&) {
                // A trajectory that does not move has no relative error.
            }
        }
        std::printf("\n");
        json["against_data_poses"] = errors;
    }

    write_kitti_poses(out / "poses.txt", poses);
    write_tum_poses(out / "poses_tum.txt", stamped);
    if (frame) {
        write_kitti_poses(out / "poses_map.txt", poses_map);
        std::vector<StampedPose> stamped_map = stamped;
        for (std::size_t i = 0; i < stamped_map.size(); ++i) {
            stamped_map[i].T_world_sensor = poses_map[i];
        }
        write_tum_poses(out / "poses_map_tum.txt", stamped_map);
    }
    write_stream_atomically(out / "stats.json",
                            [&](std::ostream& os) { os << json.dump(2) << "\n"; });
    if (!opt.quiet) {
        std::printf("wrote %s/{poses.txt, poses_tum.txt%s, stats.json}%s\n", out.c_str(),
                    frame ? ", poses_map.txt, poses_map_tum.txt" : "",
                    frame ? " (poses.txt in the frame of the poses the map started from)" : "");
    }
    if (localized == 0) {
        throw DataError("none of the " + std::to_string(records.size()) +
                        " scans of DATA was localised in '" + map_file.string() +
                        "' (their poses in " + (out / "poses.txt").string() +
                        " are predictions only): is DATA in the mapped area? Give --initial-pose "
                        "near the first scan, or a map folder with its trajectory (poses.txt or "
                        "poses_refined.txt) for the search");
    }
    return 0;
}

const RegisterCommand kLocalizeCommand(17, [](CLI::App& app, Action& action) {
    auto opt = std::make_shared<LocalizeOptions>();
    CLI::App* cmd = app.add_subcommand(
        "localize",
        "Localise every scan of DATA in a saved map (never changed): OUT/poses.txt, "
        "OUT/poses_tum.txt, OUT/stats.json (see docs/localize.md)");
    cmd->add_option("MAP", opt->map, "a `shine map` output folder, or its map.vdb")->required();
    cmd->add_option("DATA", opt->data, "scans: any input `shine map` reads")->required();
    cmd->add_option("-o,--output", opt->out, "output folder")->required();
    cmd->add_option("--initial-pose", opt->initial_pose_path,
                    "a KITTI or TUM pose file whose first pose starts the first scan (default: a "
                    "search around the map's trajectory)");
    add_scan_selection_options(cmd, opt->first_frame, opt->last_frame, opt->frame_step,
                               opt->poses_path);
    add_topic_option(cmd, opt->topic);
    cmd->add_option("--search-radius-m", opt->config.search_radius_m,
                    "how far from the prediction (or a place of the map's trajectory) a search "
                    "looks, m")
        ->capture_default_str();
    cmd->add_option("--kernel-scales-m", opt->config.kernel_scales_m,
                    "Geman-McClure scales of the coarse-to-fine registration stages, m")
        ->delimiter(',')
        ->capture_default_str();
    cmd->add_option("--start-yaw-range-deg", opt->config.start_yaw_range_deg,
                    "tracking's starts are the prediction turned about the vertical up to this "
                    "far each way (0: not turned), degrees")
        ->capture_default_str();
    cmd->add_option("--start-yaw-step-deg", opt->config.start_yaw_step_deg,
                    "in steps of this, degrees")
        ->capture_default_str();
    cmd->add_option("--prediction-good-score", opt->config.prediction_good_score,
                    "a prediction scoring at least this is tracked without trying other starts "
                    "(1: always try them)")
        ->capture_default_str();
    cmd->add_option("--track-min-start-score", opt->config.track_min_start_score,
                    "a best start scoring below this (its share of points near the surface, "
                    "weighted) goes straight to the recovery by ICP")
        ->capture_default_str();
    cmd->add_option("--start-motion-scales", opt->config.start_motion_scales,
                    "and the last motion scaled by each of these (1: constant velocity, 0: the "
                    "last pose)")
        ->delimiter(',')
        ->capture_default_str();
    cmd->add_option("--icp-lookup-voxel-m", opt->config.icp_lookup_voxel_m,
                    "the recovery's ICP finds the map surface's nearest points by voxels of this "
                    "size (0: a k-d tree search, exact and slower), m")
        ->capture_default_str();
    cmd->add_option("--icp-coarse-lookup-voxel-m", opt->config.icp_coarse_lookup_voxel_m,
                    "and in its coarse stage by voxels of this size (0: the k-d tree), m")
        ->capture_default_str();
    cmd->add_option("--icp-converged-m", opt->config.icp_converged_translation_m,
                    "each stage of the recovery's ICP stops when a step moves the pose less than "
                    "this (the SDF registration finishes the pose), m")
        ->capture_default_str();
    cmd->add_option("--icp-converged-rad", opt->config.icp_converged_rotation_rad,
                    "and turns it less than this, rad")
        ->capture_default_str();
    cmd->add_option("--search-spacing-m", opt->config.search_spacing_m,
                    "grid spacing of a search's horizontal offsets, m")
        ->capture_default_str();
    cmd->add_option("--search-headings", opt->config.search_headings,
                    "headings a search tries, 360/N degrees apart")
        ->capture_default_str();
    cmd->add_option("--deep-search-registrations", opt->config.deep_search_registrations,
                    "when a search's best candidates fail on the first lost scan of a run, the "
                    "ones ranked after them up to this many are registered too (0: not)")
        ->capture_default_str();
    cmd->add_option("--max-points", opt->config.max_points,
                    "registration points a scan at most when tracking (time grows with them)")
        ->capture_default_str();
    cmd->add_option("--recovery-max-points", opt->config.recovery_max_points,
                    "registration points a scan at most when recovering or searching")
        ->capture_default_str();
    cmd->add_option("--min-inlier-ratio", opt->config.min_inlier_ratio,
                    "share of a scan's points near the map's surface for it to count as "
                    "localised")
        ->capture_default_str();
    cmd->add_option("--threads", opt->threads, "Worker threads (0 = all cores)")
        ->capture_default_str();
    cmd->add_flag("--map-frame", opt->map_frame,
                  "write poses.txt in the map's own frame: for a map made at refined poses (with "
                  "poses_given.txt beside it), poses.txt is otherwise in the frame of the poses "
                  "it started from, and --initial-pose is read in that frame too");
    cmd->add_flag("-q,--quiet", opt->quiet, "No progress output");
    cmd->callback([opt, &action] { action = [opt] { return run_localize(*opt); }; });
});

}  // namespace
}  // namespace shine::cli
