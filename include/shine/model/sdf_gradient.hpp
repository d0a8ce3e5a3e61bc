// The neural SDF's value and its analytic spatial gradient at a batch of points.
//
// By the chain rule through the encoding (paper Fig. 2) and the decoder,
//   grad f(x) = J(x)^T h,   J = dF/dx (feature_encoding.hpp's feature_jacobian),  h = df/dF
// (Decoder::input_gradient): the same g the Eikonal term of Eq. (3) penalises. This is the
// Jacobian that scan-to-map registration needs (odometry/sdf_registration.hpp); the mapper
// adapts it to odometry's SdfField interface, so that neither module knows the other.
//
// The value is Decoder::forward's, which equals NeuralSdf::query's bit for bit (forward_lanes
// does forward's arithmetic per lane). With smoothstep interpolation the gradient is continuous
// across cells; with linear interpolation it jumps at cell faces.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "shine/model/neural_sdf.hpp"

namespace shine {

/// Per query point and level, the cell the point was last looked up in: a registration evaluates
/// the same points again and again at poses millimetres apart, so most stay in their cells and
/// skip the octree's look-up (a third of the samples of the real drive's tracking). The rows are
/// the octree's, so the results are the same bits. Valid for one octree while it does not change; a
/// query resizes it to its points (forgetting all) when their number changed.
struct QueryCellMemory {
    struct Cell {
        std::int64_t base[3] = {0, 0, 0};  ///< floor of the point / the level's cell size
        std::int32_t rows[8] = {0, 0, 0, 0, 0, 0, 0, 0};
        bool known = false;  ///< base, found and rows are set
        bool found = false;  ///< the cell is allocated (rows valid)
    };
    std::vector<Cell> cells;  ///< point-major: cells[i * num_levels + level]
};

/// SDF (m) and its gradient (map frame, per metre) at each of `points_map`, in parallel;
/// valid[i] = 0 where `mask` excludes point i (sdf 0, gradient zero there). Deterministic: each
/// point's result depends on that point alone. With `memory`, point i's cells are remembered in
/// it for the next query of the same points (the same results, faster).
void query_sdf_and_gradient(const NeuralSdf& sdf, const std::vector<Eigen::Vector3f>& points_map,
                            QueryMask mask, std::vector<float>& sdf_m,
                            std::vector<Eigen::Vector3f>& gradient_map,
                            std::vector<std::uint8_t>& valid, QueryCellMemory* memory = nullptr);

}  // namespace shine
