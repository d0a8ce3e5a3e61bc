#include "shine/io/scene_preset.hpp"

#include "shine/core/error.hpp"

namespace shine {

SceneDefaults scene_defaults(ScenePreset preset) {
    switch (preset) {
        case ScenePreset::kIndoor:
            return {0.3, 20.0, 0.05, 0.02, 0.03};
        case ScenePreset::kObject:
            return {0.1, 3.0, 0.003, 0.001, 0.0045};
        case ScenePreset::kOutdoor:
        default:
            return {1.5, 60.0, 0.2, 0.1, 0.1};
    }
}

ScenePreset scene_for_leaf(double leaf_size_m) {
    if (leaf_size_m >= 0.1) return ScenePreset::kOutdoor;
    if (leaf_size_m >= 0.01) return ScenePreset::kIndoor;
    return ScenePreset::kObject;
}

std::string to_string(ScenePreset preset) {
    switch (preset) {
        case ScenePreset::kIndoor:
            return "indoor";
        case ScenePreset::kObject:
            return "object";
        case ScenePreset::kOutdoor:
        default:
            return "outdoor";
    }
}

ScenePreset parse_scene_preset(const std::string& text, const std::string& key) {
    if (text == "outdoor") return ScenePreset::kOutdoor;
    if (text == "indoor") return ScenePreset::kIndoor;
    if (text == "object") return ScenePreset::kObject;
    throw ConfigError(key + ": expected 'outdoor', 'indoor' or 'object', got '" + text + "'");
}

}  // namespace shine
