// What kind of scene a sequence shows -- a street, a room, an object on a table -- and the length
// defaults that follow from it.
//
// Two kinds of length default exist in a mapping run, and they scale differently:
//   - Distances of the *sensor setup*: the minimum range (the vehicle or the rig itself), the
//     maximum range (what is still worth mapping). They belong to the scene, not to the map's
//     resolution: a 0.1 m outdoor map still sees 60 m. The preset decides them.
//   - The *data's accuracy*: the half-width of the band around each measured point whose samples
//     are labelled with their distance to the point's tangent plane. Range noise, pose errors and
//     surfaces that are not planar a few centimetres away decide how far that label holds, not the
//     map's resolution: on real outdoor scans a 0.1 m band is best at 0.2 m and at 0.1 m leaves,
//     on the noise-free object scene a 4.5 mm band at 3 mm leaves (docs/heldout.md,
//     docs/object_scale.md). The preset decides it.
//   - Distances of the *map's resolution*: input thinning, sigma, the normal radius. They follow
//     the leaf size (MapperConfig::finalize()).
// A preset also names a typical leaf size, used when only the scene is given; when only the leaf
// is given, the scene is inferred from it (scene_for_leaf).
#pragma once

#include <string>

namespace shine {

enum class ScenePreset { kOutdoor, kIndoor, kObject };

/// Range crop and typical leaf size of a preset, in metres.
struct SceneDefaults {
    double min_range_m = 0.0;
    double max_range_m = 0.0;
    double leaf_size_m = 0.0;
    double eval_threshold_m = 0.0;  ///< F-score threshold of the built-in evaluation
    double surface_band_m = 0.0;    ///< sampling.surface_band_m (batch mode's surface band)
};

/// outdoor: 1.5 - 60 m, 0.2 m leaves, scored at 10 cm, a 0.1 m surface band (the street and real
/// outdoor scans; PreprocessConfig's, FeatureOctreeConfig's and EvalConfig's own defaults);
/// indoor: 0.3 - 20 m, 0.05 m leaves, 2 cm, a 3 cm band (a room; the band is not measured on a
/// room yet); object: 0.1 - 3 m, 3 mm leaves, 1 mm, a 4.5 mm band (a shoebox-sized object scanned
/// from ~1 m).
SceneDefaults scene_defaults(ScenePreset preset);

/// The scene a leaf size suggests: outdoor for leaves of 0.1 m and more, indoor from 1 cm to
/// 0.1 m, object below 1 cm.
ScenePreset scene_for_leaf(double leaf_size_m);

/// "outdoor", "indoor" or "object".
std::string to_string(ScenePreset preset);

/// Parses "outdoor", "indoor" or "object"; throws ConfigError naming `key` and the choices.
ScenePreset parse_scene_preset(const std::string& text, const std::string& key);

}  // namespace shine
