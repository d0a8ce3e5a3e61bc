// Voxel downsampling of evaluation point sets: one centroid per occupied cubic voxel.
//
// The evaluation protocol thins both point sets on the same 2 cm grid so that dense and sparse
// parts of a surface weigh the same. (The io module's downsampling serves scan preprocessing in the
// sensor frame and is deliberately not reused here.)
#pragma once

#include <Eigen/Core>
#include <vector>

namespace shine {

/// Replaces the points inside each axis-aligned cubic voxel of edge `voxel_size_m` (voxel i spans
/// [i * size, (i + 1) * size) on each axis) by their centroid. The output is ordered by voxel
/// (lexicographic x, y, z index) and is the same for any thread count. Throws DataError if
/// `voxel_size_m` is not positive and finite or a point is not finite.
std::vector<Eigen::Vector3f> voxel_downsample_centroids(const std::vector<Eigen::Vector3f>& points,
                                                        double voxel_size_m);

}  // namespace shine
