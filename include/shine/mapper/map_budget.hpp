// The memory budget of a mapping run (`shine map --max-map-mb N`, config key map.max_map_mb): the
// map may not grow beyond N MB (10^6 bytes) of features + OpenVDB structure + decoder weights,
// counted as stats.json's map_bytes (NeuralSdf::memory_bytes()). The mappers check it after
// allocating each scan's cells, so a run that would not fit stops before any training.
#pragma once

#include <cstddef>
#include <filesystem>

#include "shine/core/error.hpp"
#include "shine/model/neural_sdf.hpp"

namespace shine {

/// The map grew beyond the memory budget the user set.
class MapBudgetError : public Error {
  public:
    using Error::Error;
};

/// Throws MapBudgetError when `max_map_mb` > 0 and `sdf` holds more than max_map_mb * 10^6
/// bytes. The message names the budget, the size reached, the frame (0-based index among the
/// scans mapped, and `source`, the scan's file) and how to make the map smaller: a larger leaf,
/// half-precision features, fewer levels.
void check_map_budget(const NeuralSdf& sdf, double max_map_mb, std::size_t frame,
                      const std::filesystem::path& source);

}  // namespace shine
