// Vertex colours fitted to the camera images: the colours that, interpolated over the mesh's
// triangles as a renderer does, best reproduce every pixel the mapped cameras took of the map.
//
// Each view's pixels are traced to the mesh's nearest triangle (MeshRaster's z-buffer: a wall
// behind a parked car receives none of the car's pixels) at barycentric coordinates b; pixel y
// then says b0 c0 + b1 c1 + b2 c2 = y about its triangle's vertex colours c. All pixels of all
// views give the least-squares problem
//     min_c  sum_pixels |A c - y|^2,
// kept in its normal equations A^T A c = A^T y: one symmetric 3x3 block per triangle and one
// sum per vertex, accumulated as views stream by (images never have to be in memory together;
// the memory is the mesh's). A small smoothness term joins it,
//     min_c  sum_pixels |A c - y|^2 + smoothness * sum_edges |c_i - c_j|^2,
// over every triangle's edges between two vertices a pixel reached (an edge inside the mesh so
// counts twice): normal equations (A^T A + smoothness L) c = A^T y, L the graph Laplacian. It
// holds vertices few pixels reach near their neighbours, where the pixels alone leave the fit
// loosely determined. The solve starts from the pixels' barycentric-weighted mean per vertex
// (A^T y / A^T 1, the colour a splatting renderer would give) and takes damped Jacobi steps
// c += relaxation * (A^T y - (A^T A + smoothness L) c) / diag(A^T A + smoothness L). A vertex's
// colour so averages the image over the triangles around it, as a renderer weighs it: a point
// sample at the vertex would pick one leaf of a hedge whose leaves the mesh cannot hold.
//
// Measured on the real drive's held-out images (docs/colour.md): the weighted mean of point
// samples 17.24 dB, of footprint means 17.89 dB, splatting alone 17.97 dB, three Jacobi steps
// 18.15 dB (more overfit the mapped views), against 16.66 dB for the nearest-camera baseline;
// on a later map 18.01 dB without the smoothness term, 18.03 dB with it (0.25, 8 steps: the
// steps then converge instead of stopping early), baseline 16.51 dB.
//
// Exposure: a camera's auto-exposure makes one drive's images of the same surface brighter or
// darker by several per cent (the real drive's gains 0.93-1.06). With `exposure` each view k gets
// a gain g_k, its pixels saying g_k (A_k c) = y: the gains are the ratio of each view's pixel sum
// to the sum of the colours rendered at them, normalised to geometric mean 1, and the colours are
// solved again with each view's pixels divided by its gain (the same A^T A; the right-hand side
// sum_k A_k^T y / g_k, kept per view and vertex: ~20 bytes for each vertex a view reached),
// alternating exposure_rounds times. A camera the map never saw is then rendered at the gain of
// the mapped images around it (camera_exposure.hpp): on the real drive's held-out images +0.04 to
// +0.06 dB on every split (docs/colour.md).
//
// Pixels are skipped when their surface is farther than max_range_m, and when a pixel within
// edge_margin_px shows a surface nearer by more than the occlusion tolerance: at a silhouette
// the small pose and timing errors of real data put an occluder's colour onto the surface behind.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "shine/colour/camera_view.hpp"
#include "shine/colour/mesh_raster.hpp"
#include "shine/geometry/triangle_mesh.hpp"

namespace shine {

struct VertexColourFitConfig {
    double max_range_m = 60.0;            ///< pixels whose surface is farther are not used
    int edge_margin_px = 1;               ///< silhouette margin (pixels, each way)
    double depth_tolerance_m = 0.1;       ///< a neighbour nearer by this ...
    double depth_tolerance_share = 0.05;  ///< ... plus this share of the depth marks a silhouette
    int iterations = 8;                   ///< Jacobi steps after the weighted mean
    double relaxation = 0.5;              ///< damping of each step
    /// Weight of the smoothness term per triangle edge, in the units of a pixel's squared
    /// residual (0: the pixels alone).
    double smoothness = 0.25;
    /// Fit one exposure gain per view with the colours (a camera's auto-exposure): pixel y of
    /// view k says g_k (b0 c0 + b1 c1 + b2 c2) = y; the gains' geometric mean is 1, so the
    /// colours are at the views' mean exposure.
    bool exposure = true;
    int exposure_rounds = 2;  ///< alternations of gains and colours
};

/// The fitted colours and how much image supports each vertex (sum of its barycentric weights
/// over all pixels: 0 when no camera saw it).
struct VertexColours {
    std::vector<std::array<std::uint8_t, 3>> rgb;
    std::vector<float> support;
    std::size_t coloured = 0;  ///< vertices with support > 0
    /// Each view's exposure gain, in the order the views were added (all 1 without the
    /// exposure fit; 1 for a view no pixel of which was used).
    std::vector<double> view_gains;
};

class VertexColourFit {
  public:
    /// Keeps a reference to `mesh` (it must outlive the fit).
    VertexColourFit(const TriangleMesh& mesh, const VertexColourFitConfig& config = {});

    /// Adds the pixels of `view`; `raster` is the mesh rasterised into it (rasterize_mesh).
    /// Throws DataError when the image, the raster and the camera differ in size.
    void add_view(const CameraView& view, const MeshRaster& raster);

    /// Solves for the colours (see the file comment); vertices no pixel reached get colour 0.
    VertexColours solve() const;

    std::size_t pixels_used() const { return pixels_; }

  private:
    /// One view's pixels summed per vertex it reached: A_k^T y (rgb) and A_k^T 1.
    struct ViewSums {
        std::vector<std::uint32_t> vertex;
        std::vector<std::array<float, 4>> sum;
    };

    struct Jacobi;
    Jacobi prepare_jacobi() const;
    /// The colours for right-hand side `rhs` (the file comment's solve).
    std::vector<Eigen::Vector3d> solve_colours(const Jacobi& system,
                                               const std::vector<Eigen::Vector3d>& rhs) const;

    const TriangleMesh& mesh_;
    VertexColourFitConfig config_;
    std::vector<std::array<float, 6>> blocks_;  ///< per triangle: A^T A, upper triangle row-major
    std::vector<Eigen::Vector3d> rhs_;          ///< per vertex: A^T y
    std::vector<double> support_;               ///< per vertex: A^T 1 (sum of b)
    std::size_t pixels_ = 0;
    std::vector<ViewSums> views_;     ///< per view, with the exposure fit
    std::vector<std::int32_t> slot_;  ///< scratch: a vertex's place in the view being added
};

}  // namespace shine
