// A scan as a spherical range image in its sensor frame: the nearest return per (elevation,
// azimuth) bin, for asking "what did this scan measure along that direction?".
//
// The bins are square in angle and sized from the scan itself, so that any spinning LiDAR (16 to
// 128 beams, any azimuth step) and any scene scale get an image of about one return per bin:
// with N returns spread over an elevation span E (radians) and a full turn, the bin side is
// sqrt(E * 2 pi / N) (0.29 deg for a 64-beam, 1800-column scan: between its 0.2 deg azimuth step
// and its ~0.4 deg ring spacing). Azimuth is atan2(y, x) about the sensor's z axis; elevation
// atan2(z, hypot(x, y)). Bins without a return (sky, gaps between rings) are empty and say
// nothing; the image holds 4 bytes per bin (10 with a prepared window).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace shine {

/// What a range image saw around one direction (RangeImage::nearest_around).
struct RangeLookup {
    float min_range_m = 0.0f;  ///< the nearest return in the window (meaningful if returns > 0)
    int returns = 0;           ///< bins of the window that hold a return
};

class RangeImage {
  public:
    RangeImage() = default;
    /// Builds the image from a scan's returns in its sensor frame. Points that are not finite or
    /// closer than 1e-6 m are ignored; with fewer than 2 usable returns the image is empty (every
    /// lookup finds nothing).
    explicit RangeImage(const std::vector<Eigen::Vector3f>& points_sensor);

    /// Bin side (radians).
    float bin_rad() const { return bin_rad_; }
    int rows() const { return rows_; }
    int cols() const { return cols_; }
    bool empty() const { return ranges_.empty(); }
    std::size_t memory_bytes() const {
        return (ranges_.capacity() + window_min_.capacity()) * sizeof(float) +
               window_returns_.capacity() * sizeof(std::uint16_t);
    }

    /// The nearest return among the (2 radius + 1)^2 bins centred on the bin `direction_sensor`
    /// (any length > 0) falls in; azimuth wraps around, elevation does not (bins above or below
    /// the image are empty). With prepare_window(radius_bins) done, one read of the prepared
    /// window image instead of (2 radius + 1)^2 (the same result).
    RangeLookup nearest_around(const Eigen::Vector3f& direction_sensor, int radius_bins) const;

    /// Precomputes, for every bin (and the radius_bins rows above and below the image), the
    /// nearest return and the number of returns of its window, for lookups with this radius:
    /// each image is asked many times (every point of the scans around it), so the free-space
    /// votes then read one bin per point. Radii outside 0..127 are left to the plain lookup.
    void prepare_window(int radius_bins);
    /// The radius prepare_window() was called with, -1 if none.
    int window_radius_bins() const { return window_radius_; }
    /// nearest_around() without the prepared window, bin by bin (the reference it must equal).
    RangeLookup nearest_around_bins(const Eigen::Vector3f& direction_sensor, int radius_bins) const;

  private:
    float bin_rad_ = 0.0f;
    float elevation_min_rad_ = 0.0f;
    int rows_ = 0;
    int cols_ = 0;
    std::vector<float> ranges_;  ///< row-major, 0 = no return
    int window_radius_ = -1;
    /// rows_ + 2 window_radius_ rows of cols_ (row 0 is window_radius_ below the image): the
    /// nearest return of each bin's window (0 = none) and the number of returns in it.
    std::vector<float> window_min_;
    std::vector<std::uint16_t> window_returns_;
};

}  // namespace shine
