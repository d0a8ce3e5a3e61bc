// Pairs of poses from two timestamped trajectories (TUM files), for the trajectory errors.
//
// Each estimated pose is paired with the reference pose nearest in time, if it is within
// max_time_difference_s; a reference pose serves at most one estimate and the pairs keep both
// trajectories' order (an estimate whose nearest reference pose was already taken, or lies
// before the last one taken, stays unpaired). Poses must be sorted by strictly increasing time.
#pragma once

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "shine/io/tum.hpp"

namespace shine {

/// Index pairs (estimate, reference), in increasing order of both.
using PosePairs = std::vector<std::pair<std::size_t, std::size_t>>;

/// Pairs poses by nearest timestamp within `max_time_difference_s`. Throws DataError naming
/// `estimate_source` or `reference_source` if a trajectory's times do not strictly increase,
/// ConfigError if max_time_difference_s is negative.
PosePairs associate_by_time(const std::vector<StampedPose>& estimate,
                            const std::vector<StampedPose>& reference, double max_time_difference_s,
                            const std::string& estimate_source,
                            const std::string& reference_source);

}  // namespace shine
