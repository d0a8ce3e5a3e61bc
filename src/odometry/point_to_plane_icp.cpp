// Point-to-plane ICP on the shared Levenberg-Marquardt solver.
#include "shine/odometry/point_to_plane_icp.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "shine/core/error.hpp"
#include "shine/sampling/surface_normals.hpp"

namespace shine {

namespace point_to_plane_icp_internal {
namespace {

std::vector<IndexedPoint> indexed_relative(const std::vector<Eigen::Vector3d>& points_world,
                                           const Eigen::Vector3d& origin_world) {
    std::vector<IndexedPoint> points(points_world.size());
    for (std::size_t i = 0; i < points_world.size(); ++i) {
        points[i].position = (points_world[i] - origin_world).cast<float>();
        points[i].index = static_cast<std::uint32_t>(i);
    }
    return points;
}

}  // namespace
}  // namespace point_to_plane_icp_internal

std::vector<Eigen::Vector3d> fit_plane_normals(const std::vector<Eigen::Vector3d>& points_world,
                                               std::size_t first_query, const PlaneFitConfig& fit) {
    using point_to_plane_icp_internal::indexed_relative;
    if (fit.neighbors < 5 || fit.neighbors > PointKdTree::kMaxNeighbors) {
        throw ConfigError("plane fit neighbors must be in [5, " +
                          std::to_string(PointKdTree::kMaxNeighbors) + "] (got " +
                          std::to_string(fit.neighbors) + ")");
    }
    if (!(fit.max_radius_m > 0.0)) {
        throw ConfigError("plane fit max_radius_m must be positive (got " +
                          std::to_string(fit.max_radius_m) + ")");
    }
    const std::size_t n = points_world.size();
    first_query = std::min(first_query, n);
    std::vector<Eigen::Vector3d> normals(n - first_query, Eigen::Vector3d::Zero());
    if (first_query == n) return normals;
    // Relative to the first point, in float: the tree's coordinates.
    const Eigen::Vector3d origin_world = points_world.front();
    const PointKdTree all(indexed_relative(points_world, origin_world));
    NormalConfig plane;
    plane.neighbors = fit.neighbors;
    plane.max_radius_m = static_cast<float>(fit.max_radius_m);
    const float max_sq = static_cast<float>(fit.max_radius_m * fit.max_radius_m);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(first_query, n, 256),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          PointNeighbor found[PointKdTree::kMaxNeighbors];
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              const Eigen::Vector3f q =
                                  (points_world[i] - origin_world).cast<float>();
                              const int count = all.nearest(q, fit.neighbors, max_sq, found);
                              // The orientation does not matter to a point-to-plane residual:
                              // the sensor argument equals the point, so no flip happens.
                              normals[i - first_query] =
                                  fit_plane_normal(
                                      count, [&](int k) { return found[k].position; }, q, q, plane)
                                      .cast<double>();
                          }
                      });
    return normals;
}

ReferencePlanes::ReferencePlanes(const std::vector<Eigen::Vector3d>& points_world,
                                 const PlaneFitConfig& fit) {
    const std::vector<Eigen::Vector3d> normals = fit_plane_normals(points_world, 0, fit);
    if (points_world.empty()) return;
    origin_world_ = points_world.front();
    for (std::size_t i = 0; i < points_world.size(); ++i) {
        if (normals[i].squaredNorm() > 0.0) {
            points_world_.push_back(points_world[i]);
            normals_world_.push_back(normals[i]);
        }
    }
    build_tree();
}

ReferencePlanes::ReferencePlanes(const std::vector<Eigen::Vector3d>& points_world,
                                 const std::vector<Eigen::Vector3d>& normals_world) {
    if (points_world.size() != normals_world.size()) {
        throw DataError("reference planes: " + std::to_string(points_world.size()) +
                        " points but " + std::to_string(normals_world.size()) +
                        " normals; give one normal per point");
    }
    for (std::size_t i = 0; i < points_world.size(); ++i) {
        const double norm = normals_world[i].norm();
        if (!(norm > 0.0) || !points_world[i].allFinite()) continue;
        points_world_.push_back(points_world[i]);
        normals_world_.push_back(normals_world[i] / norm);
    }
    if (!points_world_.empty()) origin_world_ = points_world_.front();
    build_tree();
}

void ReferencePlanes::build_tree() {
    tree_ =
        PointKdTree(point_to_plane_icp_internal::indexed_relative(points_world_, origin_world_));
}

void ReferencePlanes::add_voxel_lookup(double voxel_m, double radius_m) {
    VoxelNearestLookup lookup(points_world_, voxel_m, radius_m);
    auto at = lookups_.begin();
    while (at != lookups_.end() && at->radius_m() <= radius_m) ++at;
    lookups_.insert(at, std::move(lookup));
}

long ReferencePlanes::nearest(const Eigen::Vector3d& query_world, double max_distance_m,
                              long hint) const {
    for (const VoxelNearestLookup& lookup : lookups_) {
        if (lookup.radius_m() < max_distance_m) continue;
        const long j = lookup.find(query_world);
        if (j < 0 ||
            (points_world_[j] - query_world).squaredNorm() > max_distance_m * max_distance_m) {
            return -1;
        }
        return j;
    }
    PointNeighbor found[1];
    const Eigen::Vector3f q = (query_world - origin_world_).cast<float>();
    float max_sq = static_cast<float>(max_distance_m * max_distance_m);
    if (hint >= 0 && static_cast<std::size_t>(hint) < points_world_.size()) {
        // The hint's distance as the tree computes it (its position is the tree's, relative to
        // the origin in float): the nearest point is at most that far, so the search may stop
        // there. The tree keeps points at exactly the bound, so the answer is the same.
        const float hint_sq =
            point_distance_sq(q, (points_world_[hint] - origin_world_).cast<float>());
        if (hint_sq < max_sq) max_sq = hint_sq;
    }
    const int count = tree_.nearest(q, 1, max_sq, found);
    return count == 1 ? long(found[0].index) : -1;
}

long ReferencePlanes::plane_residual(const Eigen::Vector3d& point_world, double max_distance_m,
                                     double& r_m, long hint) const {
    const long j = nearest(point_world, max_distance_m, hint);
    if (j >= 0) r_m = normals_world_[j].dot(point_world - points_world_[j]);
    return j;
}

RegistrationResult register_point_to_plane(const std::vector<Eigen::Vector3f>& points_sensor,
                                           const Eigen::Isometry3d& T_world_sensor_initial,
                                           const ReferencePlanes& reference,
                                           const PointToPlaneIcpConfig& config,
                                           const SweepModel* sweep, PlaneMatches* matches) {
    if (!(config.max_correspondence_distance_m > 0.0)) {
        throw ConfigError("ICP max_correspondence_distance_m must be positive (got " +
                          std::to_string(config.max_correspondence_distance_m) + ")");
    }
    PlaneMatches own;
    PlaneMatches& match = matches ? *matches : own;
    if (match.reference.size() != points_sensor.size()) {
        match.reference.assign(points_sensor.size(), -1);
    }
    const PointResiduals residuals = [&](const std::vector<Eigen::Vector3d>& points_world,
                                         std::vector<double>& r, std::vector<Eigen::Vector3d>& g,
                                         std::vector<std::uint8_t>& valid) {
        const std::size_t n = points_world.size();
        r.assign(n, 0.0);
        g.assign(n, Eigen::Vector3d::Zero());
        valid.assign(n, 0);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256),
                          [&](const tbb::blocked_range<std::size_t>& range) {
                              for (std::size_t i = range.begin(); i != range.end(); ++i) {
                                  const long j = reference.plane_residual(
                                      points_world[i], config.max_correspondence_distance_m, r[i],
                                      match.reference[i]);
                                  match.reference[i] = static_cast<std::int32_t>(j);
                                  if (j < 0) continue;
                                  g[i] = reference.normals_world()[j];
                                  valid[i] = 1;
                              }
                          });
    };
    return minimise_point_residuals(points_sensor, T_world_sensor_initial, residuals, config.solver,
                                    sweep);
}

double point_to_plane_inlier_ratio(const std::vector<Eigen::Vector3f>& points_sensor,
                                   const Eigen::Isometry3d& T_world_sensor,
                                   const ReferencePlanes& reference, double max_correspondence_m,
                                   double inlier_m, PlaneMatches* matches) {
    const std::size_t n = points_sensor.size();
    if (n == 0) return 0.0;
    if (matches && matches->reference.size() != n) matches->reference.assign(n, -1);
    const std::size_t inliers = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, n, 256), std::size_t(0),
        [&](const tbb::blocked_range<std::size_t>& range, std::size_t count) {
            for (std::size_t i = range.begin(); i != range.end(); ++i) {
                double r_m = 0.0;
                const long j = reference.plane_residual(
                    T_world_sensor * points_sensor[i].cast<double>(), max_correspondence_m, r_m,
                    matches ? matches->reference[i] : -1);
                if (matches) matches->reference[i] = static_cast<std::int32_t>(j);
                if (j >= 0 && std::abs(r_m) <= inlier_m) ++count;
            }
            return count;
        },
        [](std::size_t a, std::size_t b) { return a + b; });
    return static_cast<double>(inliers) / static_cast<double>(n);
}

}  // namespace shine
