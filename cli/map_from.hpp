// `shine map DATA --from OLD_OUT`: what the CLI does before the old map is continued
// (docs/continue.md) -- open DATA's selection (which may hold no new scan), find and read the
// old map, and, for scans without poses, localise each one in it (mapper/map_localizer.hpp, as
// `shine localize` does) so that the new scans are trained in the old map's world frame. With no
// new scan the old map is written as the new one, unchanged.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <vector>

#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/map_sequence.hpp"
#include "shine/mapper/mapper_config.hpp"
#include "shine/model/neural_sdf.hpp"

namespace shine::cli {

/// Localises every scan of `sequence` in `sdf` (the map read from `map_file`, which it only
/// reads), the first scan found by the localiser's search around the places of the map's
/// trajectory (OLD_OUT/poses_refined.txt or poses.txt, else the poses of the data the old map
/// was made from, named in OLD_OUT/stats.json). Returns the scans that were localised, at their
/// poses; the others are skipped with a printed note. Adds a summary to `json`. Throws DataError
/// naming the map when no scan is localised.
ScanSequence localize_in_continued_map(const ScanSequence& sequence, const NeuralSdf& sdf,
                                       const std::filesystem::path& map_file, bool quiet,
                                       nlohmann::json& json);

/// Opens the scans of `data` that `options` select, as ScanSequence::open, except that
/// first_frame one past the last scan (with last_frame -1) selects none instead of being refused:
/// a drive's folder that has not grown since the old map was made from its first first_frame
/// scans has nothing new. Any other range is refused as ScanSequence::open refuses it
/// (ConfigError naming the range).
ScanSequence open_continued_selection(const std::filesystem::path& data,
                                      const ScanSequenceOptions& options);

/// A continued run with no new scan: writes `sdf` (the map read from `map_file`) into `out_dir`
/// (created if missing) as map_sequence_incremental writes a continued map that nothing trained
/// -- map.vdb with its features, decoder and origin unchanged and `config` stored with
/// incremental.decoder_weights naming `map_file`, surface.vdb and mesh.ply baked and meshed with
/// config.bake and config.mesh (the old run's files again, but for the .vdb files' random UUID,
/// when those settings are the old run's). Throws ConfigError, as IncrementalMapper::start_from,
/// naming the file and the setting when the map was made with settings other than `config`'s;
/// nothing is written then.
MapProducts write_map_without_new_scans(const MapperConfig& config, NeuralSdf& sdf,
                                        const std::filesystem::path& map_file,
                                        const std::filesystem::path& out_dir);

/// The drive a continued map was made from, so that it can vote on the new drive's movers
/// (MapToContinue): the surface beside `map_file` (its folder's mesh.ply) and the trajectory the
/// map was made along (the places the localiser searches). Either is empty when the folder does
/// not have it (a map.vdb on its own), and then the old drive does not vote; a mesh.ply that
/// cannot be read is reported (unless `quiet`) and left out the same way.
struct OldDrive {
    std::optional<TriangleMesh> surface;
    std::vector<Eigen::Isometry3d> trajectory_world;
};
OldDrive read_old_drive(const std::filesystem::path& map_file, bool quiet);

}  // namespace shine::cli
