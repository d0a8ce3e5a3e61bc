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
// The angles of the image's returns and of the lookups come from a fast arctangent wherever it
// puts them clearly inside a bin, and from std::atan2 elsewhere (near a bin edge, or for odd
// coordinates): the bins are exactly std::atan2's, so the images and votes are the same as
// with std::atan2 alone, and the votes of a scan on its neighbours cost about a fifth less.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace shine {
namespace range_image_internal {

/// A bound on |fast_atan2(y, x) - std::atan2(y, x)| in radians, with a wide margin: the largest
/// difference over 4 million directions of every octant and magnitude ratio is 4.8e-7 rad (two
/// float steps of pi; test_sampling_free_space_votes.cpp checks it stays below 1e-6).
constexpr float kFastAngleErrorRad = 2e-5f;

/// atan2(y, x) in float, within kFastAngleErrorRad of std::atan2 for finite arguments (0 for
/// x = y = 0), inlined and without std::atan2's care for the last bit. Not for NaN.
inline float fast_atan2(float y, float x) {
    // Cephes' atanf: the ratio of the smaller to the larger magnitude, reduced to
    // [-tan(pi/8), tan(pi/8)] around 0 or pi/4, then its degree-9 odd polynomial; the octant
    // from the signs and the order of |x| and |y|.
    constexpr float kPi = 3.14159265358979323846f;
    const float ax = std::fabs(x);
    const float ay = std::fabs(y);
    const float larger = std::max(ax, ay);
    if (!(larger > 0.0f)) return 0.0f;
    float a = std::min(ax, ay) / larger;
    float offset = 0.0f;
    if (a > 0.41421356237f) {
        a = (a - 1.0f) / (a + 1.0f);
        offset = kPi / 4;
    }
    const float z = a * a;
    float angle = ((((8.05374449538e-2f * z - 1.38776856032e-1f) * z + 1.99777106478e-1f) * z -
                    3.33329491539e-1f) *
                       z * a +
                   a) +
                  offset;
    if (ay > ax) angle = kPi / 2 - angle;
    if (x < 0.0f) angle = kPi - angle;
    return y < 0.0f ? -angle : angle;
}

}  // namespace range_image_internal

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
    /// The angles come from a fast arctangent where that gives the bins std::atan2 would (the
    /// same image); `exact_angles` takes std::atan2 for every return (the reference the tests
    /// compare with).
    explicit RangeImage(const std::vector<Eigen::Vector3f>& points_sensor,
                        bool exact_angles = false);

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
    /// The elevation of `direction_sensor` in bins above elevation_min_rad_ and its column before
    /// wrapping, which nearest_around_bins() computes with std::atan2: in the same bins, and
    /// with the same comparisons against whole bins, whether from std::atan2 or the fast
    /// arctangent (where it is clear of a bin edge).
    void locate(const Eigen::Vector3f& direction_sensor, float* elevation_bins, int* column) const;
    /// Elevation and azimuth of `d` from the fast arctangent; false (nothing written) where
    /// std::atan2 must give them (coordinates tiny, huge or not finite).
    static bool fast_angles(const Eigen::Vector3f& d, float* elevation_rad, float* azimuth_rad);
    /// Whether fast bin coordinates are far enough from bin edges to be std::atan2's bins, and
    /// then their floors.
    bool clear_of_edges(float elevation_bins, float azimuth_bins, int* row, int* column) const;

    float bin_rad_ = 0.0f;
    float fast_margin_bins_ = 0.0f;  ///< kFastAngleErrorRad and the rounding after it, in bins
    float inverse_bin_rad_ = 0.0f;
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
