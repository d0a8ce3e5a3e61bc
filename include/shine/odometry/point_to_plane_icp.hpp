// Point-to-plane ICP of a scan against reference points in the world frame: the registration
// while the neural map is too young to register against (Chen and Medioni 1992; Low 2004).
//
// Each scan point (at the current pose) is matched to the nearest reference point within
// max_correspondence_distance_m that has a normal; its residual is the signed distance to that
// point's tangent plane, r = n . (T p - q), whose world gradient is n. The matches are found
// again at every pose the solver tries, so the residuals, the robust kernel, the Jacobian and the
// failure rules are those of registration_solver.hpp.
//
// Reference normals come from a principal component analysis of each point's nearest neighbours
// (sampling/surface_normals.hpp's fit_plane_normal: none where the neighbourhood is not a plane),
// or from the caller. Positions are stored relative to the first reference point, so that the
// float k-d tree keeps millimetres on far-away (UTM) coordinates.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "shine/odometry/registration_solver.hpp"
#include "shine/odometry/voxel_nearest_lookup.hpp"
#include "shine/sampling/point_kdtree.hpp"

namespace shine {

/// How reference normals are estimated.
struct PlaneFitConfig {
    int neighbors = 10;         ///< k nearest reference points (at least 5)
    double max_radius_m = 1.0;  ///< neighbours farther than this are not used
};

/// Unit normals (PCA of each point's neighbourhood, as ReferencePlanes' fit) of the points
/// [first_query, size) of `points_world`, their neighbours searched among all the points; zero
/// where no plane fits. Incremental references fit each scan once, when it joins: its points
/// come last, and the earlier scans' normals stay as they were fitted. Throws ConfigError as
/// ReferencePlanes does.
std::vector<Eigen::Vector3d> fit_plane_normals(const std::vector<Eigen::Vector3d>& points_world,
                                               std::size_t first_query, const PlaneFitConfig& fit);

/// Reference points with unit normals (world frame), searchable by nearest neighbour; immutable
/// once built, so one instance serves every iteration and thread.
class ReferencePlanes {
  public:
    /// Normals by PCA of each point's neighbourhood; points without a plane are not matched.
    /// Throws ConfigError for neighbors < 5 or a non-positive radius.
    ReferencePlanes(const std::vector<Eigen::Vector3d>& points_world, const PlaneFitConfig& fit);
    /// Normals given per point (unit length; a zero normal means the point is not matched).
    /// Throws DataError if the counts differ.
    ReferencePlanes(const std::vector<Eigen::Vector3d>& points_world,
                    const std::vector<Eigen::Vector3d>& normals_world);

    /// Points that have a normal (and can be matched).
    std::size_t size() const { return points_world_.size(); }
    const std::vector<Eigen::Vector3d>& points_world() const { return points_world_; }
    const std::vector<Eigen::Vector3d>& normals_world() const { return normals_world_; }

    /// From now on, searches within up to `radius_m` are answered by a VoxelNearestLookup of
    /// `voxel_m` voxels (the point nearest to the centre of the query's voxel, if within the
    /// search's distance of the query) instead of the k-d tree: one hash look-up a search, for
    /// references searched often from far (localisation's recovery). Of several lookups the one
    /// of the smallest radius that covers the search answers. Throws ConfigError as the lookup.
    void add_voxel_lookup(double voxel_m, double radius_m);

    /// Index (into points_world()) of the nearest matchable point within max_distance_m of
    /// `query_world`, or -1. A `hint` (an index, or -1 for none), e.g. the point's match at an
    /// earlier pose, only bounds the search: the answer is the same, found faster when the hint
    /// is near. With a voxel lookup covering max_distance_m, its answer instead (hint unused).
    long nearest(const Eigen::Vector3d& query_world, double max_distance_m, long hint = -1) const;
    /// ICP's residual at `point_world`: the index of its match (nearest(), -1 for none) and,
    /// for a match, r_m = n . (point - q), the signed distance to the match's tangent plane.
    long plane_residual(const Eigen::Vector3d& point_world, double max_distance_m, double& r_m,
                        long hint = -1) const;

  private:
    void build_tree();

    Eigen::Vector3d origin_world_ = Eigen::Vector3d::Zero();
    std::vector<Eigen::Vector3d> points_world_;
    std::vector<Eigen::Vector3d> normals_world_;
    PointKdTree tree_;
    std::vector<VoxelNearestLookup> lookups_;  ///< by increasing radius
};

/// The match (an index into ReferencePlanes::points_world(), -1 for none) of each of a set of scan
/// points at the last pose they were matched at: ICP's iterations, its stages and its fitness
/// pass them on, so that each search starts from the previous match (ReferencePlanes::nearest's
/// hint). The matches found are the same with or without; an empty `reference` is no hint.
struct PlaneMatches {
    std::vector<std::int32_t> reference;
};

/// Configuration of register_point_to_plane.
struct PointToPlaneIcpConfig {
    double max_correspondence_distance_m = 1.0;  ///< farther scan points have no match
    RegistrationSolverConfig solver;             ///< kernel scale: metres off the plane
};

/// The pose T_world_sensor that puts `points_sensor` on the planes of `reference`, by
/// Levenberg-Marquardt from `T_world_sensor_initial`. With `sweep` the points are as measured
/// during the sweep, whose motion is estimated too (minimise_point_residuals). On failure
/// (result.accepted() false) the result's pose is the initial one. Throws ConfigError for a
/// non-positive correspondence distance or an invalid solver configuration. `matches`, when given,
/// hints the searches and is left with the matches of the last pose tried (PlaneMatches).
RegistrationResult register_point_to_plane(const std::vector<Eigen::Vector3f>& points_sensor,
                                           const Eigen::Isometry3d& T_world_sensor_initial,
                                           const ReferencePlanes& reference,
                                           const PointToPlaneIcpConfig& config,
                                           const SweepModel* sweep = nullptr,
                                           PlaneMatches* matches = nullptr);

/// ICP's fitness: the share of `points_sensor` that, at `T_world_sensor`, have a matchable
/// reference point within `max_correspondence_m` and lie within `inlier_m` of its tangent plane
/// (0 for no points). Used to tell a registration that found the scene from one stuck in a wrong
/// minimum, whose points mostly float off the reference planes. In parallel; `matches` as for
/// register_point_to_plane.
double point_to_plane_inlier_ratio(const std::vector<Eigen::Vector3f>& points_sensor,
                                   const Eigen::Isometry3d& T_world_sensor,
                                   const ReferencePlanes& reference, double max_correspondence_m,
                                   double inlier_m, PlaneMatches* matches = nullptr);

}  // namespace shine
