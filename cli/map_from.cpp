#include "map_from.hpp"

#include <cstdio>
#include <fstream>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/core/median.hpp"
#include "shine/core/progress.hpp"
#include "shine/io/kitti.hpp"
#include "shine/mapper/map_localizer.hpp"

namespace shine::cli {
namespace fs = std::filesystem;

namespace {
/// The trajectory the old map was made along: its folder's refined or estimated poses, else the
/// pose file of the data it was made from (stats.json "data"); empty when none is found.
std::vector<Eigen::Isometry3d> old_trajectory(const fs::path& map_file, std::string& source) {
    std::error_code ec;
    const fs::path folder = map_file.parent_path();
    std::vector<fs::path> candidates = {folder / "poses_refined.txt", folder / "poses.txt"};
    const fs::path stats = folder / "stats.json";
    if (fs::exists(stats, ec)) {
        try {
            std::ifstream in(stats);
            const nlohmann::json json = nlohmann::json::parse(in);
            if (json.contains("data") && json["data"].is_string()) {
                candidates.push_back(fs::path(json["data"].get<std::string>()) / "poses.txt");
            }
        } catch (const nlohmann::json::exception&) {
            // A damaged stats.json only loses this hint.
        }
    }
    for (const fs::path& path : candidates) {
        if (fs::exists(path, ec)) {
            source = path.string();
            return read_kitti_poses(path);
        }
    }
    source.clear();
    return {};
}
}  // namespace

fs::path continued_map_file(const std::string& from) {
    std::error_code ec;
    const fs::path path(from);
    if (fs::is_directory(path, ec)) {
        const fs::path file = path / "map.vdb";
        if (!fs::exists(file, ec)) {
            throw IoError("--from '" + from +
                          "' holds no map.vdb: give a `shine map` output folder or its map.vdb");
        }
        return file;
    }
    if (!fs::exists(path, ec)) {
        throw IoError("--from '" + from +
                      "' does not exist: give a `shine map` output folder or its map.vdb");
    }
    return path;
}

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

}  // namespace shine::cli
