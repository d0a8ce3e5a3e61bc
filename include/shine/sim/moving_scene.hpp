// Ray casting against a static scene plus rigidly moving bodies (movers) at a given time.
//
// A mover is a rigid motion of its own mesh, so a ray at time t is moved into the body's frame
// (T_world_body(t)^-1) and cast against one BVH of the body built once: exact for any time, with
// no per-time rebuild. The closest of the static hit and every mover's hit wins.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <vector>

#include "shine/geometry/ray_caster.hpp"
#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/mover_tracks.hpp"

namespace shine::sim {

/// The closed box mesh of a mover in its body frame (MoverTrack::box_body(), 12 triangles).
TriangleMesh make_mover_mesh(const MoverTrack& mover);

/// A static scene and movers on their tracks. Holds a reference to `static_scene` (which must
/// outlive it) and copies the tracks. cast() is thread-safe.
class MovingScene {
  public:
    MovingScene(const RayCaster& static_scene, MoverTracks tracks);

    /// Closest hit at `time_s`. A static hit reports its triangle as usual; a hit on mover m
    /// reports triangle_id = num_static_triangles() + m, so ids below num_static_triangles() are
    /// exactly the static scene's.
    RayHit cast(const Eigen::Vector3d& origin_m, const Eigen::Vector3d& direction_unit,
                double t_min_m, double t_max_m, double time_s) const;

    std::size_t num_static_triangles() const { return static_scene_.num_triangles(); }
    const MoverTracks& tracks() const { return tracks_; }

  private:
    const RayCaster& static_scene_;
    MoverTracks tracks_;
    std::vector<std::unique_ptr<RayCaster>> bodies_;  ///< one BVH per mover, body frame
};

}  // namespace shine::sim
