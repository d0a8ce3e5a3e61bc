// How squarely each ray meets the surface it hit, from local surface normals.
//
// A projective label (the distance along the ray) overstates the true distance to the surface by
// 1 / cos(incidence): on ground seen 25 m away from a sensor 1.7 m high a sample 0.3 m behind the
// hit is only 2 cm below the ground. Labels that disagree with the Eikonal term by a factor of
// ten bend the learned surface towards the sensor at every scan line, which shows as ripples
// between the lines. Scaling the label by |cos(incidence)| turns it into the distance to the
// local tangent plane, which agrees with both losses.
//
// Normals come from a principal component analysis of the k nearest endpoints of all rays (in
// batch mode the scans together cover the gaps between one scan's lines). Where the neighbourhood
// is not a plane (too few points, a line of points along one scan line, a corner), the cosine is
// 1: the label stays projective.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "shine/sampling/ray_set.hpp"

namespace shine {

struct IncidenceConfig {
    bool enabled = true;          ///< false: plain projective labels
    int neighbors = 16;           ///< k nearest endpoints for the normal
    float max_radius_m = 1.0f;    ///< neighbours farther than this are not used
    float min_cosine = 0.05f;     ///< lower clamp of |cos(incidence)| (labels shrink at most 20x)
    /// A neighbourhood counts as planar when its smallest covariance eigenvalue is below this
    /// fraction of the middle one, and the middle one is at least this fraction of the largest
    /// (so that a single scan line, which is a line, gives no normal).
    float max_flatness = 0.1f;
    float min_spread = 0.05f;
};

/// |cos| between each ray of `rays` and the surface normal at its endpoint, in [min_cosine, 1];
/// 1 where no normal could be estimated. Parallel; deterministic.
std::vector<float> ray_incidence_cosines(const RaySet& rays, const IncidenceConfig& config);

}  // namespace shine
