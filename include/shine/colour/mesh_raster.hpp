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
#include <array>
#include <cstdint>
#include <limits>
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

/// Where the ray of pixel (u, v) meets the plane of a triangle (Moller-Trumbore from the camera's
/// centre), in the camera's optical frame.
struct PixelTriangleHit {
    /// Barycentric weights of the triangle's corners, clamped into the triangle; a third each
    /// when the ray is parallel to the plane.
    std::array<double, 3> weights = {1.0 - 1.0 / 3.0 - 1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0};
    bool crosses_plane = false;  ///< false: the ray is parallel to the plane
    double distance_m = std::numeric_limits<double>::quiet_NaN();  ///< along the unit ray
    Eigen::Vector3d ray = Eigen::Vector3d::Zero();                 ///< the pixel's unit ray
    Eigen::Vector3d edge1 = Eigen::Vector3d::Zero();               ///< corner 1 - corner 0
    Eigen::Vector3d edge2 = Eigen::Vector3d::Zero();               ///< corner 2 - corner 0
};

/// The hit of pixel (u, v) of `camera` (at T_camera_map, the inverse of its pose) on triangle
/// `triangle` of `mesh`: how renderers and the colour fit share one pixel's barycentric weights.
PixelTriangleHit pixel_triangle_hit(const TriangleMesh& mesh, std::int32_t triangle,
                                    const RigCamera& camera, const Eigen::Isometry3d& T_camera_map,
                                    int u, int v);

}  // namespace shine
