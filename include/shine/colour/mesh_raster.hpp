// A triangle mesh rasterised into a pinhole camera: for every pixel the nearest triangle and its
// depth (a z-buffer). Colour fusion judges occlusion against it (a surface point is seen by a
// camera only if no part of the map lies in front of it in that pixel), and the photometric
// yardstick renders vertex colours through it.
//
// Pixel (u, v) covers the square around its centre at integer coordinates (io/camera_rig.hpp);
// a triangle covers a pixel when the pixel's centre lies inside its projection (top-left rule
// not needed: ties between triangles go to the nearer, then to the lower index). Depth is the
// optical frame's z, interpolated perspective-correctly. Triangles with a corner closer than
// `near_m` are left out (no clipping): at the default 0.3 m only the car's own blind spot.
//
// Triangles are binned into bands of rows and the bands rasterised in parallel; the result does
// not depend on the thread count.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/camera_rig.hpp"

namespace shine {

/// The z-buffer of one camera.
struct MeshRaster {
    int width = 0;
    int height = 0;
    std::vector<float> depth_m;          ///< optical-frame z per pixel, +inf where no triangle
    std::vector<std::int32_t> triangle;  ///< index into mesh.triangles per pixel, -1 where none

    std::size_t index(int u, int v) const { return static_cast<std::size_t>(v) * width + u; }
};

/// Rasterises `mesh` (vertices in its map frame) into `camera` at `T_map_camera`.
MeshRaster rasterize_mesh(const TriangleMesh& mesh, const RigCamera& camera,
                          const Eigen::Isometry3d& T_map_camera, double near_m = 0.3);

}  // namespace shine
