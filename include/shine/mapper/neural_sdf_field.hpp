// The neural map as the odometry's signed distance field: register_to_sdf (odometry module) sees
// an SdfField in the WORLD frame, while a NeuralSdf works in its map frame, the world translated
// by origin_world_m (map_frame.hpp). The adapter subtracts the origin in double before rounding to
// float (world coordinates may be kilometres from the origin); the frames differ by a translation
// only, so the gradient is the same vector in both.
//
// Values and gradients are query_sdf_and_gradient's (model/sdf_gradient.hpp): grad f = J^T h.
// A point is valid where the map's finest level has a cell (QueryMask::kLevel0, the observed
// region) unless another mask is given: outside it the SDF is the untrained initial features'.
#pragma once

#include "shine/model/neural_sdf.hpp"
#include "shine/model/sdf_gradient.hpp"
#include "shine/odometry/sdf_registration.hpp"

namespace shine {

/// A NeuralSdf seen as an SdfField in the world frame.
class NeuralSdfField final : public SdfField {
  public:
    /// Keeps a reference: `sdf` must outlive the field and not change while the field lives.
    /// Each point's cells are kept for the next evaluation of as many points (QueryCellMemory:
    /// the same results, faster when the points barely moved, as between a registration's
    /// iterations), so the field is evaluated by one thread at a time, as SdfField asks.
    explicit NeuralSdfField(const NeuralSdf& sdf, QueryMask mask = QueryMask::kLevel0)
        : sdf_(sdf), mask_(mask) {}

    void evaluate(const std::vector<Eigen::Vector3d>& points_world, std::vector<double>& sdf_m,
                  std::vector<Eigen::Vector3d>& gradient_world,
                  std::vector<std::uint8_t>& valid) const override;

  private:
    const NeuralSdf& sdf_;
    QueryMask mask_;
    mutable QueryCellMemory memory_;
};

}  // namespace shine
