#include "mapped_run.hpp"

#include <cmath>
#include <nlohmann/json.hpp>

#include "shine/core/error.hpp"
#include "shine/io/file_contents.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/run_deskew_record.hpp"

namespace shine::cli {
namespace fs = std::filesystem;

namespace {

/// A run given the sequence's poses wrote them to poses_given.txt unchanged (to 1e-9 m in
/// the text); a millimetre apart is another pose file or another sequence.
constexpr double kSamePoseTolM = 1e-3;

}  // namespace

std::string MappedRun::describe() const {
    std::string text = poses_world_sensor.empty()
                           ? "at the sequence's poses (the run did not refine them)"
                           : "at the run's refined poses (poses_refined.txt)";
    if (deskew) {
        text +=
            sweep ? ", deskewed as the run was (times from the azimuth: " + sweep->describe() + ")"
                  : ", deskewed as the run was (by the scans' own times, where they have them)";
    } else {
        text += ", as measured (the run did not deskew)";
    }
    return text;
}

ScanSequence MappedRun::apply(const ScanSequence& sequence) const {
    ScanSequence result =
        poses_world_sensor.empty() ? sequence : sequence.with_poses(poses_world_sensor);
    if (sweep) result = result.with_sweep_times(*sweep);
    return result;
}

MappedRun read_mapped_run(const fs::path& run_dir, const ScanSequence& sequence) {
    const fs::path stats_path = run_dir / "stats.json";
    const std::string text = read_file_contents(
        stats_path, "run stats", "the stats.json of a `shine map` output folder (--run OUT)");
    // The deskew record first: it also fails on text that is not a JSON object.
    const RunDeskewRecord deskew = read_run_deskew_record(text, stats_path.string());
    if (nlohmann::json::parse(text).contains("odometry")) {
        // It placed its held-out scans by its estimate (stats.json "heldout_local") and scored
        // them at the sequence's poses as well ("heldout"), both printed by the run itself.
        throw ConfigError("'" + stats_path.string() +
                          "': the run estimated its poses; --run scores runs that were given "
                          "poses (the run's own held-out figures are its stats.json heldout and "
                          "heldout_local)");
    }
    MappedRun run;
    const fs::path refined_path = run_dir / "poses_refined.txt";
    if (fs::exists(refined_path)) {
        std::vector<Eigen::Isometry3d> refined = read_kitti_poses(refined_path);
        if (refined.size() != sequence.size()) {
            throw DataError("'" + refined_path.string() + "' holds " +
                            std::to_string(refined.size()) + " poses, the sequence " +
                            std::to_string(sequence.size()) +
                            " scans: the run mapped another sequence (or another --frames)");
        }
        const fs::path given_path = run_dir / "poses_given.txt";
        if (fs::exists(given_path)) {
            const std::vector<Eigen::Isometry3d> given = read_kitti_poses(given_path);
            for (std::size_t i = 0; i < sequence.size(); ++i) {
                const double apart_m =
                    i < given.size()
                        ? (given[i].translation() - sequence.pose(i).translation()).norm()
                        : INFINITY;
                if (!(apart_m <= kSamePoseTolM)) {
                    throw DataError("'" + given_path.string() + "': scan " + std::to_string(i) +
                                    (i < given.size() ? " lies " + std::to_string(apart_m) +
                                                            " m from the sequence's pose"
                                                      : " is missing") +
                                    ": the run was given other poses than this sequence's");
                }
            }
        }
        run.poses_world_sensor = std::move(refined);
    }
    if (deskew.active) {
        DeskewConfig config;
        config.scan_period_s = deskew.scan_period_s;
        run.deskew = config;
        run.sweep = deskew.sweep;
    }
    return run;
}

}  // namespace shine::cli
