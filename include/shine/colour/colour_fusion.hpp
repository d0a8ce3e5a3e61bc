// Colour of surface points fused from camera images, with occlusion judged against the map's own
// surface.
//
// A point p (map frame) with normal n takes colour from every view whose camera sees it:
//   - in front of the camera (z >= near_m) and inside the image;
//   - not occluded: the map's surface in p's pixel (MeshRaster) is no nearer than p's depth minus
//     a tolerance (depth_tolerance_m + depth_tolerance_share * z), so a wall behind a parked car
//     or a hedge does not take their colour;
//   - not near an occluder's silhouette: no pixel within edge_margin_px of p's pixel holds a
//     surface nearer than that tolerance. Real poses and the camera's trigger time are off by
//     centimetres and milliseconds; near a silhouette that shifts the occluder's colour onto the
//     surface behind it, so such views are left to the cameras that see the point clear of edges;
//   - not at a grazing angle: cos(n, direction to the camera) >= min_cos (when n is known);
//   - no farther than max_range_m.
// Each view's colour is the image's mean over the point's footprint (a square of footprint_m at
// the point's depth, from a summed-area table; a bilinear sample where that is under two pixels):
// one colour per vertex cannot hold a texture finer than the vertices (a hedge's leaves), and the
// mean over its footprint is the colour that errs least against it. The point's colour is the
// weighted mean of the views' colours, weight cos / max(z^2, 1 m^2): near, frontal views resolve
// the surface best and are the least blurred by pose errors. Means are of 8-bit sRGB values (the
// images' encoding).
//
// Views are added one at a time (ColourAccumulator), so a long drive's images never have to be
// in memory together.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "shine/colour/camera_view.hpp"
#include "shine/colour/mesh_raster.hpp"

namespace shine {

struct ColourFusionConfig {
    double near_m = 0.3;             ///< points nearer a camera than this are not coloured by it
    double max_range_m = 60.0;       ///< nor farther than this (the LiDAR's default reach)
    double depth_tolerance_m = 0.1;  ///< occlusion tolerance at the camera ...
    double depth_tolerance_share = 0.02;  ///< ... plus this share of the depth
    int edge_margin_px = 2;               ///< silhouette margin (pixels, each way)
    double footprint_m = 0.0;  ///< side of the square a point's colour averages (0: a point sample)
    double min_cos = 0.15;     ///< grazing views below this cosine are ignored
    /// true: each point takes the single view of largest weight instead of the weighted mean
    /// (sharper where poses are exact, blotchier where they are not; measured in docs/colour.md).
    bool best_view_only = false;
};

/// The fused colour of each point and the weight behind it (0: no camera saw it).
struct FusedColours {
    std::vector<std::array<std::uint8_t, 3>> rgb;
    std::vector<float> weight;
    std::size_t coloured = 0;  ///< points with weight > 0
};

/// Fuses colours view by view into points fixed at construction.
class ColourAccumulator {
  public:
    /// Keeps references to `points_map` and `normals_map` (same length; DataError otherwise),
    /// which must outlive the accumulator.
    ColourAccumulator(const std::vector<Eigen::Vector3d>& points_map,
                      const std::vector<Eigen::Vector3d>& normals_map,
                      const ColourFusionConfig& config);
    /// Adds what `view` sees of the points, occlusion judged against `raster` (the map's mesh
    /// rasterised into that view). Parallel over the points. Throws DataError when the image,
    /// the raster and the camera differ in size.
    void add_view(const CameraView& view, const MeshRaster& raster);
    /// The fused colours so far.
    FusedColours result() const;

  private:
    const std::vector<Eigen::Vector3d>& points_map_;
    const std::vector<Eigen::Vector3d>& normals_map_;
    ColourFusionConfig config_;
    std::vector<Eigen::Vector3d> sum_;
    std::vector<double> weight_;
    std::vector<double> best_;
};

/// Fuses the colours of `points_map` (normals_map: unit normals, or zero where unknown; same
/// length) from `views`, occlusion judged against `rasters` (one per view: the map's mesh
/// rasterised into that view). Points no view sees get weight 0 and colour 0. Parallel; the
/// result does not depend on the thread count. Throws DataError for mismatched lengths.
FusedColours fuse_colours(const std::vector<Eigen::Vector3d>& points_map,
                          const std::vector<Eigen::Vector3d>& normals_map,
                          const std::vector<CameraView>& views,
                          const std::vector<MeshRaster>& rasters,
                          const ColourFusionConfig& config = {});

/// Bilinear sample of `image` at pixel coordinates (u, v) (centres at integers), clamped to the
/// image; channels as doubles in [0, 255].
Eigen::Vector3d sample_bilinear(const RgbImage& image, double u, double v);

}  // namespace shine
