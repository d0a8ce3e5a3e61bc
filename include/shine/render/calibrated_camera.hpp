// A map's mesh seen through a calibrated camera of the sequence's rig (io/camera_rig.hpp), with
// the surface's own colours: what `shine render --calibrated-camera` sets beside the photo that
// camera took (docs/render.md).
//
// One z-buffer (colour/mesh_raster.hpp) decides which triangle each pixel shows, so all layers
// agree on the surface. The pixel's ray meets that triangle's plane at barycentric coordinates
// (w0, w1, w2) (perspective-correct, clamped into the triangle, exactly as the held-out colour
// yardstick's render_vertex_colours computes them), and the layers are
//   range.V        distance from the camera's centre to that point along the ray (m; not z-depth);
//   normal.X/Y/Z   the triangle's unit normal in the world frame, turned to face the camera;
//   color.R/G/B    (meshes with vertex colours) sum_k w_k rgb_k, the 8-bit sRGB vertex colours
//                  interpolated as the yardstick does, decoded to linear light (IEC 61966-2-1
//                  transfer function, sRGB / Rec. 709 primaries, 0..1): what compositors and
//                  Blender expect in an EXR;
//   intensity.V    (meshes with intensity) the vertex intensities interpolated, as the sensor
//                  gives them; NaN where a corner's is unknown;
// each NaN where the pixel shows no surface.
//
// The 8-bit picture (`image`) is, with vertex colours, the interpolated sRGB values rounded: pixel
// for pixel render_vertex_colours' image (tested), so score_rendering() on it is the held-out
// PSNR `shine map` reports. Without colours it is grey: the intensity scaled by its 99th
// percentile over the mesh's vertices, or, without intensity either, shaded by the angle between
// the ray and the surface (255 * (0.25 + 0.75 |cos|), a headlight at the camera).
#pragma once

#include <Eigen/Geometry>

#include "shine/colour/photometric_score.hpp"
#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/camera_rig.hpp"
#include "shine/render/exr_image.hpp"

namespace shine {

/// What the 8-bit picture of a calibrated camera view shows.
enum class CameraShading : std::uint8_t {
    kVertexColour,  ///< the mesh's vertex colours (sRGB)
    kIntensity,     ///< the mesh has no colours: its LiDAR intensity as grey
    kShadedGrey     ///< neither: grey shaded by the viewing angle
};

/// A rendered calibrated camera view: float layers and the 8-bit picture with its hit mask.
struct CalibratedCameraRendering {
    ExrImage layers{1, 1};
    ColourRendering picture;  ///< image + hit (1 where the pixel shows a triangle)
    CameraShading shading = CameraShading::kShadedGrey;
    /// kIntensity: the intensity shown white (the 99th percentile of the vertices' finite
    /// values); 0 otherwise.
    double intensity_white = 0.0;
};

/// Renders `mesh` (vertices in its map frame) through `camera` at `T_map_camera` (optical frame ->
/// map frame: colour/camera_view.hpp's camera_pose_in_map). Layers and picture as in the file
/// comment. Vertex colours are scaled by `exposure_gain` (the camera's exposure against the
/// colours', as render_vertex_colours scales them; the 8-bit value clamped at 255, the linear one
/// at 1); triangles with a corner nearer than `near_m` are left out (MeshRaster).
/// Parallel; the result does not depend on the thread count. Throws DataError for a mesh without
/// triangles or with a vertex_rgb / vertex_intensity whose size is not the vertex count.
CalibratedCameraRendering render_calibrated_camera(const TriangleMesh& mesh,
                                                   const RigCamera& camera,
                                                   const Eigen::Isometry3d& T_map_camera,
                                                   double exposure_gain = 1.0, double near_m = 0.3);

/// sRGB-encoded value (0..1) to linear light (IEC 61966-2-1).
double srgb_to_linear(double encoded);

}  // namespace shine
