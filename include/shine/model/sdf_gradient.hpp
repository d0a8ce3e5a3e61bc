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

/// SDF (m) and its gradient (map frame, per metre) at each of `points_map`, in parallel;
/// valid[i] = 0 where `mask` excludes point i (sdf 0, gradient zero there). Deterministic: each
/// point's result depends on that point alone.
void query_sdf_and_gradient(const NeuralSdf& sdf, const std::vector<Eigen::Vector3f>& points_map,
                            QueryMask mask, std::vector<float>& sdf_m,
                            std::vector<Eigen::Vector3f>& gradient_map,
                            std::vector<std::uint8_t>& valid);

}  // namespace shine
