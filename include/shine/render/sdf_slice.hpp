// A slice of the neural SDF on an axis-aligned plane (`--slice z=1.5`): the signed distance the
// map's decoder gives at every pixel of the plane, over the map's observed extent.
//
// The plane is given in world coordinates (x=, y= or z= metres). Pixels are pixel_m wide (default:
// the map's leaf size) and cover the bounding box of the finest level's allocated cells; the
// SDF is queried at each pixel's centre and is NaN where the finest level has no cell (the
// unobserved region, where the decoder's output means nothing). Image axes, so that a slice reads
// like a map or an elevation:
//   z=: image x = world x (right), image y = world -y (north up);
//   y=: image x = world x (right), image y = world -z (up);
//   x=: image x = world y (right), image y = world -z (up).
// The EXR has one channel, "sdf.V" (m, positive in free space), and header attributes giving the
// world position of pixel (0, 0)'s centre and the pixel size.
#pragma once

#include <string>

#include "shine/model/neural_sdf.hpp"
#include "shine/render/exr_image.hpp"

namespace shine {

/// An axis-aligned plane: axis 0, 1, 2 (x, y, z) = value_m (world frame).
struct SlicePlane {
    int axis = 2;
    double value_m = 0.0;

    /// "z1.50": the name used in output files.
    std::string label() const;
};

/// Parses "x=1.5", "y=-2" or "z=0.3". Throws ConfigError naming the text otherwise.
SlicePlane parse_slice_plane(const std::string& text);

/// Slice resolution.
struct SdfSliceConfig {
    double pixel_m = 0.0;  ///< pixel size; 0 = the map's leaf size
};

/// The SDF on `plane`. Throws DataError if the map has no cells, if the plane misses the map's
/// extent (naming the extent) or if the image would exceed 32768 pixels a side (suggesting a
/// larger pixel_m); ConfigError for a negative pixel_m.
ExrImage slice_neural_sdf(const NeuralSdf& sdf, const SlicePlane& plane,
                          const SdfSliceConfig& config = {});

}  // namespace shine
