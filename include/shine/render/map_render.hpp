// Images of a map's surface from a sensor pose: every pixel's ray cast into the map's triangle
// mesh (the same closest-hit RayCaster the held-out yardstick uses), giving
//   range.V   predicted range along the ray (m), NaN where the ray meets no surface;
//   normal.X, normal.Y, normal.Z
//             unit normal of the hit triangle in the world frame, turned to face the sensor;
//             NaN where no hit;
// and, when the rays carry the scan's measured ranges (the spherical LiDAR model),
//   measured.V the scan's range in that pixel (m), NaN where the LiDAR had no return;
//   error.V   measured - predicted (m, signed), NaN where either is missing. Negative: the map's
//             surface lies behind what the LiDAR saw (a hole, or an object the map lacks);
//             positive: the map has surface in front of the measured point (a phantom surface).
// Ranges are Euclidean distances from the sensor along the pixel's ray (not z-depth). Every name
// is layer.channel: Blender reads such a file as a multilayer EXR with one pass per quantity
// (it rejects a bare name like "range", and then drops that channel).
#pragma once

#include <Eigen/Geometry>

#include "shine/geometry/ray_caster.hpp"
#include "shine/geometry/triangle_mesh.hpp"
#include "shine/render/exr_image.hpp"
#include "shine/render/pixel_rays.hpp"

namespace shine {

/// How far rays are followed.
struct MapRenderConfig {
    double max_range_m = 200.0;  ///< rays meeting nothing closer are misses
};

/// A map's mesh and its ray caster (built once; render() is thread-safe).
class MeshRenderer {
  public:
    /// Keeps a reference to `mesh` (it must outlive the renderer). Throws DataError for a mesh
    /// without triangles and the RayCaster's ConfigError for a broken one.
    explicit MeshRenderer(const TriangleMesh& mesh);

    /// Renders `rays` from the sensor pose `T_world_sensor` (world frame; the mesh's
    /// origin_world_m is taken into account). Channels as in the file comment. Parallel; the
    /// result does not depend on the thread count.
    ExrImage render(const PixelRays& rays, const Eigen::Isometry3d& T_world_sensor,
                    const MapRenderConfig& config = {}) const;

  private:
    const TriangleMesh& mesh_;
    RayCaster caster_;
};

}  // namespace shine
