// `shine map DATA --from OLD_OUT`: what the CLI does before the old map is continued
// (docs/continue.md) -- find and read the old map, and, for scans without poses, localise each
// one in it (mapper/map_localizer.hpp, as `shine localize` does) so that the new scans are
// trained in the old map's world frame.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "shine/io/scan_sequence.hpp"
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

}  // namespace shine::cli
