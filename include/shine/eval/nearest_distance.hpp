// Nearest-neighbour distances from one point set to another, with a k-d tree (nanoflann).
#pragma once

#include <Eigen/Core>
#include <vector>

namespace shine {

/// For each of `queries`, the Euclidean distance (m) to the nearest of `targets`, capped at
/// `max_distance_m`: a query with no target within the cap (or an empty `targets`) gets exactly
/// `max_distance_m`. The cap also bounds the search, so a small cap makes queries faster. Queries
/// run in parallel (TBB); the result does not depend on the thread count.
/// Throws DataError if `max_distance_m` is not positive (infinity is allowed).
std::vector<float> nearest_distances_m(const std::vector<Eigen::Vector3f>& targets,
                                       const std::vector<Eigen::Vector3f>& queries,
                                       double max_distance_m);

}  // namespace shine
