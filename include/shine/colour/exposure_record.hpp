// The mapped images' exposure gains (camera_exposure.hpp) as a `shine map` run's stats.json
// records them, so that `shine render --calibrated-camera` and the held-out yardstick render a
// camera at the exposure its neighbours had:
//
//   "appearance": {..., "exposure": [{"camera": "image_00", "frame": 0, "gain": 1.048}, ...]}
#pragma once

#include <string>
#include <string_view>

#include "shine/colour/camera_exposure.hpp"

namespace shine {

/// The "exposure" array of a stats.json's "appearance" object for `track`, as JSON text.
std::string exposure_record_json(const ExposureTrack& track);

/// Parses a stats.json text. No "appearance" object, or no "exposure" in it: an empty track
/// (every camera at gain 1; maps made without images, or before gains were fitted). Throws
/// DataError naming `source` for text that is not a JSON object, an "exposure" that is not an
/// array of objects with a camera name, a frame number and a finite positive gain.
ExposureTrack read_exposure_record(std::string_view stats_json, const std::string& source);

}  // namespace shine
