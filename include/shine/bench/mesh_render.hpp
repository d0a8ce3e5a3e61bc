// Pictures of triangle meshes for reports: orthographic, z-buffered rasterisation with Lambert
// shading (two-sided, a light over the viewer's shoulder), optionally coloured per vertex, e.g. by
// the distance to a reference mesh. Deterministic and dependency-free (draws into an RgbImage).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "shine/core/png_image.hpp"
#include "shine/geometry/triangle_mesh.hpp"

namespace shine {

/// Where the camera looks from (orthographic) and what it frames.
struct MeshRenderView {
    double azimuth_deg = -60.0;   ///< direction from the scene to the camera, around world z
    double elevation_deg = 45.0;  ///< above the horizontal; 90 looks straight down
    /// World box the panel frames (its projection fills the panel, aspect kept); triangles
    /// outside it are still drawn where they fall inside the panel. Empty: the mesh's bounds.
    Eigen::AlignedBox3f bounds;
};

/// Renders `mesh` into the panel [x0, x0 + width) x [y0, y0 + height) of `image` (other pixels
/// untouched). `vertex_colours` is empty (every triangle `base_colour`) or one colour per
/// vertex (a triangle takes the mean of its three). Throws DataError if vertex_colours has
/// another size or a triangle refers to a missing vertex.
void render_mesh(RgbImage& image, int x0, int y0, int width, int height, const TriangleMesh& mesh,
                 const MeshRenderView& view, const std::vector<Rgb>& vertex_colours = {},
                 Rgb base_colour = {200, 200, 205});

/// Colour of an error of `value` on a scale from 0 (light blue-grey) through yellow to
/// `max_value` and beyond (red).
Rgb error_colour(double value, double max_value);

}  // namespace shine
