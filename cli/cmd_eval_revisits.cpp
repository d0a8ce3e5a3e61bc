// `shine eval-revisits DATA POSES...`: how consistent trajectories are where they come back to a
// place (odometry/revisit_consistency.hpp). Scan pairs far apart in the sequence but near in
// space are registered to each other directly, and each trajectory's relative pose of the pair
// is compared with that registration: a measure of drift that needs no ground truth, and that
// scores a reference trajectory (a LiDAR-inertial estimate, say) the same way as an estimate.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "command_registry.hpp"
#include "shine/core/error.hpp"
#include "shine/core/median.hpp"
#include "shine/core/progress.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/odometry/revisit_consistency.hpp"

namespace shine::cli {
namespace {

struct EvalRevisitsOptions {
    std::string data;
    std::vector<std::string> pose_paths;
    int holdout_every = 0;
    int min_gap = 10;
    double max_distance_m = 5.0;
    double max_range_m = 40.0;
    double voxel_m = 0.3;
    double min_inlier_ratio = 0.5;
    int threads = 0;
    bool json = false;
    bool quiet = false;
};

/// One trajectory's poses for the scans of the sequence that have one (`scans`, ascending).
struct Trajectory {
    std::string path;
    std::vector<std::size_t> scans;
    std::vector<Eigen::Isometry3d> T_world_sensor;  ///< one per entry of `scans`
};

/// Reads a KITTI pose file holding one pose per scan of the sequence or, with --holdout-every,
/// one per mapped scan (as `shine map --holdout-every N` writes them).
Trajectory read_trajectory(const std::string& path, std::size_t num_scans,
                           const HoldoutSplit& split, int holdout_every) {
    Trajectory t;
    t.path = path;
    t.T_world_sensor = read_kitti_poses(path);
    const std::size_t n = t.T_world_sensor.size();
    if (n == num_scans) {
        for (std::size_t i = 0; i < n; ++i) t.scans.push_back(i);
        return t;
    }
    if (holdout_every > 0 && n == split.mapped.size()) {
        t.scans = split.mapped;
        return t;
    }
    std::string expected = std::to_string(num_scans) + " (one per scan)";
    if (holdout_every > 0) {
        expected += " or " + std::to_string(split.mapped.size()) + " (one per scan mapped with " +
                    "--holdout-every " + std::to_string(holdout_every) + ")";
    } else {
        expected += "; a run with --holdout-every N wrote one per mapped scan: give the same N";
    }
    throw DataError("pose file '" + path + "' has " + std::to_string(n) +
                    " poses for a sequence of " + std::to_string(num_scans) + " scans: expected " +
                    expected);
}

/// The pose of scan `scan` in `t`, or nullptr when `t` has none for it.
const Eigen::Isometry3d* pose_of(const Trajectory& t, std::size_t scan) {
    const auto it = std::lower_bound(t.scans.begin(), t.scans.end(), scan);
    if (it == t.scans.end() || *it != scan) return nullptr;
    return &t.T_world_sensor[static_cast<std::size_t>(it - t.scans.begin())];
}

int run_eval_revisits(const EvalRevisitsOptions& options) {
    const auto threads = limit_threads(options.threads);
    ScanSequenceOptions open;
    open.poses = PoseFileUse::kIfPresent;
    const ScanSequence sequence = ScanSequence::open(options.data, open);
    const HoldoutSplit split = split_holdout(sequence, options.holdout_every);
    std::vector<Trajectory> trajectories;
    for (const std::string& path : options.pose_paths) {
        trajectories.push_back(
            read_trajectory(path, sequence.size(), split, options.holdout_every));
    }

    RevisitConfig config;
    config.min_gap_scans = static_cast<std::size_t>(options.min_gap);
    config.max_distance_m = options.max_distance_m;
    config.max_range_m = options.max_range_m;
    config.voxel_size_m = options.voxel_m;
    config.min_inlier_ratio = options.min_inlier_ratio;
    if (!(config.max_range_m > config.min_range_m)) {
        throw ConfigError("--max-range-m must be above " + std::to_string(config.min_range_m) +
                          " m");
    }
    // The pairs, by the first trajectory, among the scans every trajectory has a pose for.
    const Trajectory& chooser = trajectories.front();
    std::vector<Eigen::Isometry3d> chooser_poses;
    std::vector<std::size_t> chooser_scans;
    for (std::size_t k = 0; k < chooser.scans.size(); ++k) {
        const std::size_t scan = chooser.scans[k];
        const bool everywhere = std::all_of(trajectories.begin(), trajectories.end(),
                                            [&](const Trajectory& t) { return pose_of(t, scan); });
        if (!everywhere) continue;
        chooser_scans.push_back(scan);
        chooser_poses.push_back(chooser.T_world_sensor[k]);
    }
    const std::vector<RevisitPair> pairs = find_revisits(chooser_poses, chooser_scans, config);

    struct Row {
        std::size_t first, second;
        double distance_m;
        RevisitRegistration registration;
        std::vector<PoseDisagreement> disagreement;  ///< per trajectory
    };
    std::vector<Row> rows;
    Progress progress("revisits", pairs.size(), !options.quiet && !options.json);
    for (std::size_t p = 0; p < pairs.size(); ++p) {
        const std::size_t a = chooser_scans[pairs[p].first], b = chooser_scans[pairs[p].second];
        const Scan first = sequence.load(a), second = sequence.load(b);
        const Eigen::Isometry3d start =
            chooser_poses[pairs[p].first].inverse() * chooser_poses[pairs[p].second];
        Row row{a,
                b,
                pairs[p].distance_m,
                register_revisit(first.points_sensor, second.points_sensor, start, config),
                {}};
        if (row.registration.accepted) {
            for (const Trajectory& t : trajectories) {
                const Eigen::Isometry3d relative = pose_of(t, a)->inverse() * *pose_of(t, b);
                row.disagreement.push_back(
                    pose_disagreement(relative, row.registration.T_first_second));
            }
        }
        rows.push_back(std::move(row));
        progress.update(p + 1);
    }
    progress.finish();

    std::size_t accepted = 0;
    for (const Row& row : rows) accepted += row.registration.accepted ? 1 : 0;
    struct Summary {
        double median_m = 0, max_m = 0, median_deg = 0, max_deg = 0;
    };
    std::vector<Summary> summaries(trajectories.size());
    for (std::size_t t = 0; t < trajectories.size(); ++t) {
        std::vector<double> m, deg;
        for (const Row& row : rows) {
            if (!row.registration.accepted) continue;
            m.push_back(row.disagreement[t].translation_m);
            deg.push_back(row.disagreement[t].rotation_deg);
        }
        summaries[t].median_m = median(m);
        summaries[t].median_deg = median(deg);
        summaries[t].max_m = m.empty() ? 0.0 : *std::max_element(m.begin(), m.end());
        summaries[t].max_deg = deg.empty() ? 0.0 : *std::max_element(deg.begin(), deg.end());
    }

    if (options.json) {
        nlohmann::json j;
        j["data"] = options.data;
        j["holdout_every"] = options.holdout_every;
        j["min_gap_scans"] = options.min_gap;
        j["max_distance_m"] = options.max_distance_m;
        j["pairs"] = rows.size();
        j["registered_pairs"] = accepted;
        nlohmann::json list = nlohmann::json::array();
        for (std::size_t t = 0; t < trajectories.size(); ++t) {
            list.push_back({{"poses", trajectories[t].path},
                            {"median_translation_m", summaries[t].median_m},
                            {"max_translation_m", summaries[t].max_m},
                            {"median_rotation_deg", summaries[t].median_deg},
                            {"max_rotation_deg", summaries[t].max_deg}});
        }
        j["trajectories"] = list;
        nlohmann::json per_pair = nlohmann::json::array();
        for (const Row& row : rows) {
            nlohmann::json r = {{"first", row.first},
                                {"second", row.second},
                                {"distance_m", row.distance_m},
                                {"registered", row.registration.accepted},
                                {"inlier_ratio", row.registration.inlier_ratio}};
            nlohmann::json d = nlohmann::json::array();
            for (const PoseDisagreement& x : row.disagreement) {
                d.push_back({{"translation_m", x.translation_m}, {"rotation_deg", x.rotation_deg}});
            }
            r["disagreement"] = d;
            per_pair.push_back(r);
        }
        j["per_pair"] = per_pair;
        std::printf("%s\n", j.dump(2).c_str());
        return 0;
    }
    std::printf(
        "revisits of %s: %zu scan pairs at least %d scans apart and within %g m (by %s), "
        "%zu registered (inlier share >= %g)\n",
        options.data.c_str(), rows.size(), options.min_gap, options.max_distance_m,
        chooser.path.c_str(), accepted, options.min_inlier_ratio);
    if (rows.empty()) {
        std::printf(
            "no revisits: the trajectory does not come back within %g m after %d scans "
            "(see --max-distance-m, --min-gap)\n",
            options.max_distance_m, options.min_gap);
        return 0;
    }
    std::printf("\n%s", "pair        m apart  inliers");
    for (std::size_t t = 0; t < trajectories.size(); ++t) {
        std::printf("   #%zu cm    deg", t + 1);
    }
    std::printf("\n");
    for (const Row& row : rows) {
        std::printf("%5zu-%-5zu %7.2f  %7.2f", row.first, row.second, row.distance_m,
                    row.registration.inlier_ratio);
        if (!row.registration.accepted) {
            std::printf("   not registered\n");
            continue;
        }
        for (const PoseDisagreement& d : row.disagreement) {
            std::printf("  %6.2f %6.3f", d.translation_m * 100, d.rotation_deg);
        }
        std::printf("\n");
    }
    std::printf("\ndisagreement with the direct registrations (%zu pairs):\n", accepted);
    std::printf("  %-3s %12s %12s %12s %12s  %s\n", "", "median cm", "max cm", "median deg",
                "max deg", "poses");
    for (std::size_t t = 0; t < trajectories.size(); ++t) {
        std::printf("  #%-2zu %12.2f %12.2f %12.3f %12.3f  %s\n", t + 1,
                    summaries[t].median_m * 100, summaries[t].max_m * 100, summaries[t].median_deg,
                    summaries[t].max_deg, trajectories[t].path.c_str());
    }
    return 0;
}

const RegisterCommand kEvalRevisitsCommand(52, [](CLI::App& app, Action& action) {
    auto options = std::make_shared<EvalRevisitsOptions>();
    CLI::App* cmd = app.add_subcommand(
        "eval-revisits",
        "Score trajectories where they revisit a place, without ground truth: scan pairs far "
        "apart in the sequence but near in space are registered to each other directly "
        "(point-to-plane ICP), and each trajectory's relative pose of the pair is compared with "
        "that registration (its drift between the visits)");
    cmd->add_option("DATA", options->data, "the scans (a directory or a recording)")->required();
    cmd->add_option("POSES", options->pose_paths,
                    "KITTI pose files, one pose per scan (or per mapped scan with "
                    "--holdout-every); the first chooses the pairs")
        ->required();
    cmd->add_option("--holdout-every", options->holdout_every,
                    "pose files of a run with --holdout-every N hold the mapped scans only")
        ->check(CLI::Range(0, 1000000))
        ->capture_default_str();
    cmd->add_option("--min-gap", options->min_gap, "pairs at least this many scans apart")
        ->check(CLI::Range(1, 1000000))
        ->capture_default_str();
    cmd->add_option("--max-distance-m", options->max_distance_m, "pairs at most this far apart, m")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    cmd->add_option("--max-range-m", options->max_range_m, "points beyond this range are not used")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    cmd->add_option("--voxel-m", options->voxel_m,
                    "the registered scan's thinning voxel, m (the reference's: a third)")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    cmd->add_option("--min-inlier-ratio", options->min_inlier_ratio,
                    "share of points within 0.1 m of a plane for a registration to count")
        ->check(CLI::Range(0.0, 1.0))
        ->capture_default_str();
    cmd->add_option("--threads", options->threads, "worker threads (0: all cores)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    cmd->add_flag("--json", options->json, "print one JSON object");
    cmd->add_flag("-q,--quiet", options->quiet, "no progress line");
    cmd->callback(
        [options, &action] { action = [options] { return run_eval_revisits(*options); }; });
});

}  // namespace
}  // namespace shine::cli
