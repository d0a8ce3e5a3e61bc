// `shine map`'s colour and reflectance step (mapper/surface_appearance.hpp) and its held-out
// colour yardstick (colour/photometric_score.hpp), with what they print and put in stats.json.
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>
#include <optional>

#include "cli_common.hpp"
#include "shine/colour/camera_exposure.hpp"
#include "shine/colour/reflectance_voxels.hpp"
#include "shine/io/camera_rig.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/mapper_config.hpp"
#include "shine/mapper/written_surface.hpp"

namespace shine::cli {

/// The cameras of a sequence folder (none for a recording). Throws what find_camera_rig throws,
/// so a broken calibration fails before any mapping.
std::optional<CameraRig> find_sequence_cameras(const ScanSequence& selected, bool quiet);

/// Adds colour and reflectance to OUT's mesh.ply and surface.vdb from the scans of `mapped` (at
/// the poses the map was made at; `reflectance`: their intensities if mapping accumulated them);
/// prints a line and sets json["appearance"] when it did. `written`: the products' level set and
/// mesh in memory (taken over), or null to read them from OUT. Returns the images' exposure gains
/// (empty without images).
ExposureTrack add_map_appearance(const std::filesystem::path& out, const ScanSequence& mapped,
                                 const MapperConfig& config, const std::optional<CameraRig>& rig,
                                 const ReflectanceVoxels* reflectance, WrittenSurface* written,
                                 nlohmann::json& json);

/// With cameras and held-out scans: OUT/mesh.ply's colours rendered into the held-out scans'
/// cameras (at `scored`'s poses, each at the exposure `exposure` gives its frame) and compared
/// with their images, beside the naive baseline; prints the pooled PSNRs and sets
/// json["heldout_colour"].
void score_heldout_colours(const std::filesystem::path& out, const ScanSequence& scored,
                           const HoldoutSplit& split, const std::optional<CameraRig>& rig,
                           const ExposureTrack& exposure, nlohmann::json& json);

}  // namespace shine::cli
