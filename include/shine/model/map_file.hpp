// The neural map on disk: a .vdb file with one standard Int32Grid per feature level (voxels = node
// corners, values = rows of the feature table, OpenVDB's default 5-4-3 tree whatever the layout in
// memory) and, as file metadata, the feature table (float32 "shine_float_array" or float16
// "shine_half_array", named by "shine_feature_precision"; maps without that key are float32), the
// decoder weights, the map origin, each level's index shift and the configuration. Standard OpenVDB
// tools (vdb_print) list the grids; ShineVDB reloads the map and answers identical SDF queries.
#pragma once

#include <filesystem>
#include <string>

#include "shine/model/neural_sdf.hpp"

namespace shine {

/// Writes `sdf` to `path` atomically. `config_text` (the mapping configuration, as YAML) is stored
/// for provenance.
void save_neural_map(const std::filesystem::path& path, const NeuralSdf& sdf,
                     const std::string& config_text);

/// A map read back from disk.
struct LoadedMap {
    NeuralSdf sdf;
    std::string config_text;
};

/// Reads a map written by save_neural_map. Throws IoError naming the file on a missing, corrupt or
/// foreign .vdb (not a ShineVDB map, inconsistent sizes, out-of-range rows).
LoadedMap load_neural_map(const std::filesystem::path& path);

/// Bytes of the file on disk.
std::size_t file_bytes(const std::filesystem::path& path);

}  // namespace shine
