// Surface normals at the ray endpoints, for labels that agree with the Eikonal term.
//
// A projective label (the distance along the ray) overstates the distance to the surface by
// 1 / cos(incidence): on ground 25 m away from a sensor 1.7 m high, a sample 0.3 m behind the hit
// along the ray is only 2 cm below the ground. Labels that disagree with the Eikonal term by a
// factor of ten bend the learned surface towards the sensor at every scan line, which shows as
// ripples between the lines; and a band that is 2 cm thick across the surface leaves the space
// just behind it unconstrained. With a normal, the sampler places surface samples along the
// normal (labels are then true distances to the tangent plane) and scales free-space labels by
// |cos(incidence)| (ray_sampler.hpp).
//
// Normals come from a principal component analysis of the k nearest endpoints of all rays (in
// batch mode the scans together cover the gaps between one scan's lines). Where the neighbourhood
// is not a plane (too few points, a single scan line, a corner), there is no normal and the
// ray's labels stay projective.
#pragma once

#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <vector>

#include "shine/sampling/ray_set.hpp"

namespace shine {

struct NormalConfig {
    bool enabled = true;        ///< false: plain projective labels along the rays
    int neighbors = 16;         ///< k nearest endpoints for the normal
    float max_radius_m = 1.0f;  ///< neighbours farther than this are not used
    /// A neighbourhood counts as planar when its smallest covariance eigenvalue is below
    /// max_flatness times the middle one, and the middle one is at least min_spread times the
    /// largest (so that a single scan line, which is a line, gives no normal).
    float max_flatness = 0.1f;
    float min_spread = 0.05f;
};

/// The unit normal of the plane fitted to `count` points by a principal component analysis (the
/// covariance's eigenvector of the smallest eigenvalue), pointing from `endpoint` towards
/// `sensor`; the zero vector when there are fewer than 5 points or they do not form a plane
/// (NormalConfig::max_flatness, min_spread). `point_at(i)` gives the i-th point. The sums run in
/// index order in double, so two callers that list the same points in the same order get the
/// same bits (the tests' reference searches rely on it).
template <class PointAt>
Eigen::Vector3f fit_plane_normal(int count, const PointAt& point_at,
                                 const Eigen::Vector3f& endpoint, const Eigen::Vector3f& sensor,
                                 const NormalConfig& config) {
    if (count < 5) return Eigen::Vector3f::Zero();
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (int i = 0; i < count; ++i) mean += point_at(i).template cast<double>();
    mean /= count;
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    for (int i = 0; i < count; ++i) {
        const Eigen::Vector3d d = point_at(i).template cast<double>() - mean;
        covariance += d * d.transpose();
    }
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(covariance);
    const Eigen::Vector3d lambda = eig.eigenvalues();  // ascending
    if (!(lambda(2) > 0.0)) return Eigen::Vector3f::Zero();
    if (lambda(0) > config.max_flatness * lambda(1)) return Eigen::Vector3f::Zero();  // no plane
    if (lambda(1) < config.min_spread * lambda(2)) return Eigen::Vector3f::Zero();    // a line
    Eigen::Vector3d normal = eig.eigenvectors().col(0).normalized();
    if (normal.dot((sensor - endpoint).cast<double>()) < 0.0) normal = -normal;
    return normal.cast<float>();
}

/// Unit normal at each ray's endpoint, oriented towards the ray's sensor; the zero vector where
/// no normal could be estimated. Parallel; deterministic.
std::vector<Eigen::Vector3f> estimate_ray_normals(const RaySet& rays, const NormalConfig& config);

/// As above, but estimates normals only for the rays [ray_begin, ray_end) (zero elsewhere), still
/// from the neighbourhoods among all of `rays`' endpoints: incremental mode estimates the
/// current scan's normals with the recent scans' endpoints filling the gaps between its lines.
std::vector<Eigen::Vector3f> estimate_ray_normals(const RaySet& rays, const NormalConfig& config,
                                                  std::size_t ray_begin, std::size_t ray_end);

}  // namespace shine
