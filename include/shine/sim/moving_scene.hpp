// Ray casting against a static scene plus rigidly moving bodies (movers) at a given time.
//
// A mover is a rigid motion of its own mesh, so a ray at time t is moved into the body's frame
// (T_world_body(t)^-1) and cast against one BVH of the body built once: exact for any time, with
// no per-time rebuild. The closest of the static hit and every present mover's hit wins (a mover
// is present from its first waypoint's time to its last's, io/mover_tracks.hpp).
//
// A scan selects its part of the scene once (select): the static blocks within the sensor's range
// (a city, BlockRayCaster) and the movers present during its sweep whose path comes within that
// range, so a city with hundreds of movers costs each ray only the few near it. A selection's hits
// are exactly those of the whole scene for rays from its point within its radius and time span.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <vector>

#include "shine/geometry/ray_caster.hpp"
#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/mover_tracks.hpp"
#include "shine/sim/block_ray_caster.hpp"

namespace shine::sim {

/// The closed box mesh of a mover in its body frame (MoverTrack::box_body(), 12 triangles).
TriangleMesh make_mover_mesh(const MoverTrack& mover);

class MovingScene;

/// The part of a MovingScene that rays from one point reach within a radius and a time span (one
/// scan). Cheap to make; cast() is thread-safe. Refers to its scene, which must outlive it.
class MovingSceneSelection {
  public:
    /// Closest hit at `time_s` (MovingScene::cast's contract) among the selected static blocks and
    /// movers.
    RayHit cast(const Eigen::Vector3d& origin_m, const Eigen::Vector3d& direction_unit,
                double t_min_m, double t_max_m, double time_s) const;

    /// Indices of the selected movers, ascending.
    const std::vector<std::size_t>& movers() const { return movers_; }

  private:
    friend class MovingScene;
    const MovingScene* scene_ = nullptr;
    BlockSelection blocks_;  ///< used when the scene's static part is in blocks
    std::vector<std::size_t> movers_;
};

/// A static scene (one mesh or a city in blocks) and movers on their tracks. Holds a reference to
/// the static scene (which must outlive it) and copies the tracks. cast() is thread-safe.
class MovingScene {
  public:
    MovingScene(const RayCaster& static_scene, MoverTracks tracks);
    MovingScene(const BlockRayCaster& static_scene, MoverTracks tracks);

    /// Closest hit at `time_s`. A static hit reports its triangle as usual; a hit on mover m
    /// reports triangle_id = num_static_triangles() + m, so ids below num_static_triangles() are
    /// exactly the static scene's.
    RayHit cast(const Eigen::Vector3d& origin_m, const Eigen::Vector3d& direction_unit,
                double t_min_m, double t_max_m, double time_s) const;

    /// The static blocks within `radius_m` of `point_m` and the movers present at some time in
    /// [begin_s, end_s] whose box comes within `radius_m` of it then: exact for rays from
    /// `point_m` up to `radius_m` long cast at times in that span.
    MovingSceneSelection select(const Eigen::Vector3d& point_m, double radius_m, double begin_s,
                                double end_s) const;

    std::size_t num_static_triangles() const;
    const MoverTracks& tracks() const { return tracks_; }

  private:
    friend class MovingSceneSelection;
    MovingScene(const RayCaster* static_mesh, const BlockRayCaster* static_blocks,
                MoverTracks tracks);
    /// Adds mover m's hit at `time_s` to `best` when it is present and nearer.
    void cast_mover(std::size_t m, const Eigen::Vector3d& origin_m,
                    const Eigen::Vector3d& direction_unit, double t_min_m, double t_max_m,
                    double time_s, RayHit& best) const;

    const RayCaster* static_mesh_ = nullptr;  ///< one of the two is set
    const BlockRayCaster* static_blocks_ = nullptr;
    MoverTracks tracks_;
    std::vector<std::unique_ptr<RayCaster>> bodies_;  ///< one BVH per mover, body frame
};

}  // namespace shine::sim
