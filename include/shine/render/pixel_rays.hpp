// The rays of an image: one unit direction per pixel in the sensor frame, and optionally the
// range the scan measured along it. Both projections (the spherical LiDAR model and the pinhole
// camera) produce them; the renderer casts them into a map.
#pragma once

#include <Eigen/Core>
#include <vector>

namespace shine {

/// One ray per pixel, row-major with row 0 at the top.
struct PixelRays {
    int width = 0;
    int height = 0;
    std::vector<Eigen::Vector3d> directions_sensor;  ///< unit vectors, one per pixel
    /// Empty, or one range per pixel: the scan's return in that pixel (m), NaN where none.
    std::vector<float> measured_range_m;

    std::size_t num_pixels() const { return static_cast<std::size_t>(width) * height; }
};

}  // namespace shine
