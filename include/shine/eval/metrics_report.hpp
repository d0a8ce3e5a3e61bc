// Human-readable and JSON renderings of MeshMetrics.
#pragma once

#include <string>

#include "shine/eval/mesh_metrics.hpp"

namespace shine {

/// A multi-line block for terminals: distances in cm, ratios in %, point counts and density.
std::string format_metrics(const MeshMetrics& metrics);

/// One JSON object with every field of `metrics` under its C++ name (metres, ratios in [0, 1]);
/// `indent` < 0 gives a single line.
std::string metrics_to_json(const MeshMetrics& metrics, int indent = -1);

}  // namespace shine
