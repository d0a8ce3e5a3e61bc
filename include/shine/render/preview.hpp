// PNG previews of float images for a quick look: a colour per pixel and, below the image, a
// legend bar with the scale's end values and unit.
//
// Colour maps: sequential (range: dark blue - teal - yellow, near to far) and diverging (error,
// SDF: blue for negative, white at zero, red for positive); values beyond the scale saturate.
// Pixels without a value (NaN) are black unless the layout says otherwise; normals map each
// component from [-1, 1] to [0, 255] (x red, y green, z blue: the usual normal-map colours). LiDAR
// images are much wider than tall, so rows are repeated to make the preview at least min_height_px
// tall.
#pragma once

#include <string>
#include <vector>

#include "shine/core/png_image.hpp"

namespace shine {

/// A colour scale for one quantity.
struct ColourScale {
    double min = 0.0;
    double max = 1.0;
    bool diverging = false;  ///< blue-white-red centred between min and max
    std::string unit = "m";
};

/// How previews are laid out.
struct PreviewLayout {
    int min_height_px = 256;  ///< rows are repeated until the image is at least this tall
    int max_width_px = 4096;  ///< wider images keep their width (columns are never dropped)
    /// Draw the zero level (black where a pixel's sign differs from its right or lower
    /// neighbour's): the surface in an SDF slice.
    bool zero_level = false;
    /// Colour of pixels whose value is NaN while `other` (below) has a value: e.g. error pixels
    /// where the LiDAR saw something but the map has no surface.
    Rgb missing_colour = {0, 0, 0};
    Rgb nan_colour = {0, 0, 0};  ///< pixels without a value
};

/// The colour of `value` on `scale` (NaN gives black).
Rgb scale_colour(double value, const ColourScale& scale);

/// A preview of one channel (width x height values, row-major) titled `title`. `other`, when not
/// empty, marks pixels shown in layout.missing_colour: value NaN but other[i] finite.
RgbImage preview_scalar(const std::vector<float>& values, int width, int height,
                        const ColourScale& scale, const std::string& title,
                        const PreviewLayout& layout = {}, const std::vector<float>& other = {});

/// A preview of unit normals (three channels), titled `title`.
RgbImage preview_normals(const std::vector<float>& nx, const std::vector<float>& ny,
                         const std::vector<float>& nz, int width, int height,
                         const std::string& title, const PreviewLayout& layout = {});

/// The q-quantile (0..1) of the finite values; `fallback` if there are none.
double finite_quantile(const std::vector<float>& values, double q, double fallback);

}  // namespace shine
