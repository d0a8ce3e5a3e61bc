// The colour yardstick without ground truth: the coloured mesh rendered into the cameras of scans
// the map never saw (held out), compared with the images those cameras took.
//
//   render_vertex_colours()  each pixel's nearest triangle (MeshRaster), its vertex colours
//                            interpolated perspective-correctly at the pixel's ray
//   score_rendering()        PSNR = 10 log10(255^2 / MSE) over the pixels whose ray meets the
//                            map (MSE over the three channels of 8-bit values), and the share of
//                            such pixels
//   nearest_camera_colours() the naive baseline: each vertex takes the colour of the single
//                            nearest camera (by centre) whose image it projects into, without any
//                            occlusion test
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "shine/colour/camera_view.hpp"
#include "shine/colour/mesh_raster.hpp"
#include "shine/geometry/triangle_mesh.hpp"

namespace shine {

/// A rendered image and which of its pixels show the map.
struct ColourRendering {
    RgbImage image{1, 1};
    std::vector<std::uint8_t> hit;  ///< 1 where the pixel's ray meets a triangle
};

/// Renders `mesh` with `vertex_rgb` (one per vertex) as seen by `camera` at `T_map_camera`.
/// Pixels meeting no triangle are black. `exposure_gain` scales the colours (the camera's
/// exposure against the one the colours were fitted at; camera_exposure.hpp). Throws DataError
/// for a wrong vertex_rgb size.
ColourRendering render_vertex_colours(const TriangleMesh& mesh,
                                      const std::vector<std::array<std::uint8_t, 3>>& vertex_rgb,
                                      const RigCamera& camera,
                                      const Eigen::Isometry3d& T_map_camera,
                                      double exposure_gain = 1.0);

/// How a rendering compares with the image the camera took.
struct PhotometricScore {
    double psnr_db = 0.0;    ///< over hit pixels; 0 when there is none
    double mse = 0.0;        ///< mean squared error per channel (8-bit units)
    double hit_share = 0.0;  ///< hit pixels / all pixels
    std::size_t hit_pixels = 0;
};

/// Scores `rendering` against `image` (same size; DataError otherwise).
PhotometricScore score_rendering(const ColourRendering& rendering, const RgbImage& image);

/// PSNR of a pooled MSE (several frames: their squared errors summed over all their hit pixels).
double psnr_from_mse(double mse);

/// Bilinear sample of `image` at pixel coordinates (u, v) (centres at integers), clamped to the
/// image; channels as doubles in [0, 255].
Eigen::Vector3d sample_bilinear(const RgbImage& image, double u, double v);

/// The naive baseline's vertex colours (see the file comment); vertices no camera sees are black.
std::vector<std::array<std::uint8_t, 3>> nearest_camera_colours(
    const TriangleMesh& mesh, const std::vector<CameraView>& views);

}  // namespace shine

namespace shine {

/// One held-out image: the coloured map's score and the naive baseline's on the same mesh.
struct HeldoutImageScore {
    std::size_t scan_index = 0;
    std::filesystem::path image_path;
    PhotometricScore map;       ///< the mesh's own vertex colours
    PhotometricScore baseline;  ///< nearest_camera_colours() from the mapped views
};

/// Every held-out image scored (see the file comment), and the pooled PSNRs over all their hit
/// pixels.
struct HeldoutColourScores {
    std::vector<HeldoutImageScore> frames;
    double map_psnr_db = 0.0;
    double baseline_psnr_db = 0.0;
    double hit_share = 0.0;  ///< over all held-out pixels
};

/// Scores `mesh` (with vertex_rgb) in the `heldout` views; the baseline colours come from
/// `mapped` views. `heldout_gains` (empty, or one per held-out view): the exposure each
/// held-out camera is rendered at (the mapped cameras' around it, camera_exposure.hpp); the
/// baseline's colours carry their camera's exposure as they are. Throws DataError when the mesh
/// has no colours or the gains do not match the views.
HeldoutColourScores score_heldout_images(const TriangleMesh& mesh,
                                         const std::vector<CameraView>& mapped,
                                         const std::vector<CameraView>& heldout,
                                         const std::vector<double>& heldout_gains = {});

}  // namespace shine
