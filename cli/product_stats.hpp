// The stats.json entries every command that writes map products shares: "map" (sizes of the
// neural map), "surface" (the baked level set) and "mesh".
#pragma once

#include <filesystem>
#include <nlohmann/json.hpp>

#include "shine/mapper/map_sequence.hpp"
#include "shine/model/neural_sdf.hpp"

namespace shine::cli {

/// Sets json["map"], json["surface"] and json["mesh"] for `sdf` and the products written into
/// `out` (file sizes are read from out/map.vdb and out/surface.vdb).
void add_product_stats(nlohmann::json& json, const NeuralSdf& sdf, const MapProducts& products,
                       const std::filesystem::path& out);

}  // namespace shine::cli
