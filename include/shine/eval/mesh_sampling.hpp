// Uniform random points on the surface of a triangle mesh, for evaluation.
//
// Each triangle receives a number of samples proportional to its area: the expected count
// area_m2 * density_per_m2 is rounded up or down at random (stochastic rounding), so the total is
// unbiased even for triangles much smaller than 1 / density. Points are uniform inside each
// triangle. Every triangle draws from its own generator, seeded from (seed, triangle index), so the
// result depends only on the mesh, the density and the seed: not on the thread count or schedule.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "shine/geometry/triangle_mesh.hpp"

namespace shine {

/// Which triangles of a mesh take part in sampling and area sums.
enum class FaceSelection {
    kAll,       ///< every triangle
    kObserved,  ///< triangles whose face_observed flag is non-zero (all, if the flags are empty)
};

/// Triangles with an area at or below this (m^2) are degenerate: they get no samples and no area.
inline constexpr double kDegenerateTriangleAreaM2 = 1e-12;

/// Surface area in m^2 of the selected, non-degenerate triangles.
/// Throws DataError if a vertex index is out of range or face_observed has the wrong length.
double mesh_surface_area_m2(const TriangleMesh& mesh, FaceSelection faces = FaceSelection::kAll);

/// Draws about `density_per_m2` points per square metre, uniformly over the selected,
/// non-degenerate triangles of `mesh` (see the file comment). Points are ordered by triangle.
/// Throws DataError if `density_per_m2` is not positive and finite, if a vertex index is out of
/// range, or if face_observed is neither empty nor one flag per triangle.
std::vector<Eigen::Vector3f> sample_mesh_surface(const TriangleMesh& mesh, double density_per_m2,
                                                 std::uint64_t seed,
                                                 FaceSelection faces = FaceSelection::kAll);

}  // namespace shine
