#include "map_from.hpp"

#include <cstdio>
#include <fstream>
#include <optional>
#include <vector>

#include "saved_map.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/median.hpp"
#include "shine/core/progress.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/ply.hpp"
#include "shine/mapper/incremental_mapper.hpp"
#include "shine/mapper/map_localizer.hpp"

namespace shine::cli {
namespace fs = std::filesystem;

namespace {
/// The trajectory the old map was made along: its folder's (saved_map_trajectory), else the pose
/// file of the data it was made from (stats.json "data"); empty when none is found.
std::vector<Eigen::Isometry3d> old_trajectory(const fs::path& map_file, std::string& source) {
    std::vector<Eigen::Isometry3d> trajectory = saved_map_trajectory(map_file, source);
    if (!trajectory.empty()) return trajectory;
    std::error_code ec;
    const fs::path stats = map_file.parent_path() / "stats.json";
    if (!fs::exists(stats, ec)) return {};
    try {
        std::ifstream in(stats);
        const nlohmann::json json = nlohmann::json::parse(in);
        if (json.contains("data") && json["data"].is_string()) {
            const fs::path poses = fs::path(json["data"].get<std::string>()) / "poses.txt";
            if (fs::exists(poses, ec)) {
                source = poses.string();
                return read_kitti_poses(poses);
            }
        }
    } catch (const nlohmann::json::exception&) {
        // A damaged stats.json only loses this hint.
    }
    return {};
}
}  // namespace

ScanSequence localize_in_continued_map(const ScanSequence& sequence, const NeuralSdf& sdf,
                                       const fs::path& map_file, bool quiet, nlohmann::json& json) {
    std::string places_source;
    const std::vector<Eigen::Isometry3d> places = old_trajectory(map_file, places_source);
    const LocalizeConfig config;
    MapLocalizer localizer(sdf, config, places);
    if (!quiet) {
        std::printf("localising the scans in %s first (%s)\n", map_file.c_str(),
                    places.empty()
                        ? "first scan searched around the world origin only: no "
                          "trajectory beside the map"
                        : ("first scan searched around the places of " + places_source).c_str());
    }
    std::vector<std::size_t> localized;
    std::vector<Eigen::Isometry3d> poses;
    std::vector<double> seconds;
    std::size_t skipped = 0;
    {
        Progress progress("localize", sequence.size());
        for (std::size_t i = 0; i < sequence.size(); ++i) {
            const Scan scan = sequence.load(i);
            const LocalizeRecord& r = localizer.localize(scan.points_sensor);
            seconds.push_back(r.seconds);
            if (r.localized) {
                localized.push_back(i);
                poses.push_back(r.T_world_sensor);
            } else {
                ++skipped;
                if (!quiet) {
                    std::printf(
                        "\nscan %zu (%s): not localised in the map (%.0f %% of %llu points on its "
                        "surface): skipped, not mapped\n",
                        i, scan.source.filename().c_str(), 100.0 * r.inlier_ratio,
                        static_cast<unsigned long long>(r.points));
                }
            }
            progress.update(i + 1, to_string(r.source));
        }
        progress.finish();
    }
    json = {{"poses", "localised in the map"},
            {"places", places_source},
            {"scans", sequence.size()},
            {"localised", localized.size()},
            {"skipped", skipped},
            {"median_seconds_per_scan", median(seconds)}};
    if (!quiet) {
        std::printf("localised %zu of %zu scans in the map (median %.1f ms a scan)%s\n",
                    localized.size(), sequence.size(), 1000.0 * median(seconds),
                    skipped > 0 ? "; the others are not mapped" : "");
    }
    if (localized.empty()) {
        throw DataError("no scan of '" + sequence.directory().string() +
                        "' was localised in map '" + map_file.string() +
                        "': the data does not overlap the map, or give the scans' poses in the "
                        "map's world frame (a pose file)");
    }
    return sequence.subset(localized).with_poses(poses);
}

ScanSequence open_continued_selection(const fs::path& data, const ScanSequenceOptions& options) {
    try {
        return ScanSequence::open(data, options);
    } catch (const ConfigError&) {
        if (options.first_frame < 1 || options.last_frame != -1 || options.frame_step < 1) throw;
        ScanSequenceOptions all = options;
        all.first_frame = 0;
        std::optional<ScanSequence> scans;
        try {
            scans = ScanSequence::open(data, all);
        } catch (const Error&) {
            // The range's own error (rethrown below) is the one to report.
        }
        if (!scans || scans->size() != static_cast<std::size_t>(options.first_frame)) throw;
        return scans->subset({});
    }
}

MapProducts write_map_without_new_scans(const MapperConfig& config, NeuralSdf& sdf,
                                        const fs::path& map_file, const fs::path& out_dir) {
    // The set-up of map_sequence_incremental's continued run, so that the map is checked against
    // the run's settings as any continued map is, and stored with the same configuration.
    MapperConfig mapper_config = config;
    mapper_config.finalize();
    mapper_config.incremental.decoder_weights = "none";  // the old map's decoder, not loaded
    IncrementalMapper mapper(mapper_config);
    mapper.start_from(std::move(sdf), map_file.string());
    mapper.release_training_state();
    MapperConfig stored = config;
    stored.finalize();
    stored.incremental.decoder_weights = map_file.string();
    sdf = std::move(mapper.sdf());
    ensure_directory(out_dir);
    return write_map_products(sdf, stored, out_dir);
}

OldDrive read_old_drive(const fs::path& map_file, bool quiet) {
    OldDrive old;
    std::string source;
    old.trajectory_world = old_trajectory(map_file, source);
    const fs::path mesh = map_file.parent_path() / "mesh.ply";
    std::error_code ec;
    if (old.trajectory_world.empty() || !fs::exists(mesh, ec)) return old;
    try {
        old.surface = read_ply_mesh(mesh);
    } catch (const Error& e) {
        if (!quiet) {
            std::printf("note: the old drive does not vote on the new drive's movers: %s\n",
                        e.what());
        }
    }
    return old;
}

}  // namespace shine::cli
