#include "shine/sampling/range_image.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace shine {
namespace {
constexpr float kTwoPi = 6.28318530717958647692f;
constexpr float kMinRangeM = 1e-6f;
/// (2 r + 1)^2 returns must fit the window image's 16-bit counts.
constexpr int kMaxWindowRadiusBins = 127;
/// How far a fast angle may be from std::atan2's, with the rounding of its sums with pi or the
/// lowest elevation (a few float ulps of pi) and of sqrt against std::hypot.
constexpr float kFastAngleMarginRad = range_image_internal::kFastAngleErrorRad + 1e-6f;

float azimuth_of(const Eigen::Vector3f& d) { return std::atan2(d.y(), d.x()); }
float elevation_of(const Eigen::Vector3f& d) { return std::atan2(d.z(), std::hypot(d.x(), d.y())); }
}  // namespace

RangeImage::RangeImage(const std::vector<Eigen::Vector3f>& points_sensor, bool exact_angles) {
    // The angles of every return once, in parallel (the image is built for every scan): from the
    // fast arctangent where it can be used (fast_angles), else from std::atan2 (exact[i] = 1).
    // The image must be the one std::atan2's angles give: the extreme elevations, which size the
    // image, are recomputed with std::atan2 among the returns the fast ones leave in doubt, and
    // so are the bins of returns whose fast angles lie near a bin edge.
    const std::size_t n = points_sensor.size();
    std::vector<float> range_m(n), elevation_rad(n), azimuth_rad(n);
    std::vector<std::uint8_t> exact(n, 0);
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, n, 4096),
        [&](const tbb::blocked_range<std::size_t>& block) {
            for (std::size_t i = block.begin(); i != block.end(); ++i) {
                const Eigen::Vector3f& p = points_sensor[i];
                const float r = p.allFinite() ? p.norm() : 0.0f;
                range_m[i] = r >= kMinRangeM ? r : 0.0f;
                if (range_m[i] == 0.0f) continue;
                if (exact_angles || !fast_angles(p, &elevation_rad[i], &azimuth_rad[i])) {
                    elevation_rad[i] = elevation_of(p);
                    azimuth_rad[i] = azimuth_of(p);
                    exact[i] = 1;
                }
            }
        });
    std::size_t usable = 0;
    float el_min = 10.0f, el_max = -10.0f;
    for (std::size_t i = 0; i < n; ++i) {
        if (range_m[i] == 0.0f) continue;
        el_min = std::min(el_min, elevation_rad[i]);
        el_max = std::max(el_max, elevation_rad[i]);
        ++usable;
    }
    if (usable < 2) return;
    if (!exact_angles) {
        // The lowest exact elevation is a return whose fast one is within twice the error of the
        // lowest fast one (and the highest likewise).
        const float doubt_rad = 2.0f * kFastAngleMarginRad;
        const float low = el_min + doubt_rad, high = el_max - doubt_rad;
        el_min = 10.0f;
        el_max = -10.0f;
        for (std::size_t i = 0; i < n; ++i) {
            if (range_m[i] == 0.0f) continue;
            if (elevation_rad[i] <= low || elevation_rad[i] >= high) {
                const float el = exact[i] ? elevation_rad[i] : elevation_of(points_sensor[i]);
                el_min = std::min(el_min, el);
                el_max = std::max(el_max, el);
            }
        }
    }
    // About one return per bin over the solid angle the scan covers (file comment); a scan in one
    // plane still gets bins of its own azimuth spacing.
    const float span_rad = std::max(el_max - el_min, kTwoPi / static_cast<float>(usable));
    bin_rad_ = std::sqrt(span_rad * kTwoPi / static_cast<float>(usable));
    cols_ = std::max(1, static_cast<int>(std::ceil(kTwoPi / bin_rad_)));
    bin_rad_ = kTwoPi / static_cast<float>(cols_);  // a whole number of columns fills the turn
    fast_margin_bins_ = kFastAngleMarginRad / bin_rad_;
    inverse_bin_rad_ = 1.0f / bin_rad_;
    elevation_min_rad_ = el_min;
    rows_ = static_cast<int>(std::floor((el_max - el_min) / bin_rad_)) + 1;
    ranges_.assign(static_cast<std::size_t>(rows_) * static_cast<std::size_t>(cols_), 0.0f);
    for (std::size_t i = 0; i < n; ++i) {
        const float r = range_m[i];
        if (r == 0.0f) continue;
        float el_bins = (elevation_rad[i] - elevation_min_rad_) / bin_rad_;
        float az_bins = (azimuth_rad[i] + kTwoPi / 2) / bin_rad_;
        int row, col;
        if (exact[i] || !clear_of_edges(el_bins, az_bins, &row, &col)) {
            if (!exact[i]) {
                el_bins = (elevation_of(points_sensor[i]) - elevation_min_rad_) / bin_rad_;
                az_bins = (azimuth_of(points_sensor[i]) + kTwoPi / 2) / bin_rad_;
            }
            row = static_cast<int>(el_bins);
            col = static_cast<int>(az_bins);
        }
        row = std::clamp(row, 0, rows_ - 1);
        col = std::clamp(col, 0, cols_ - 1);
        float& bin = ranges_[static_cast<std::size_t>(row) * cols_ + col];
        if (bin == 0.0f || r < bin) bin = r;
    }
}

inline bool RangeImage::fast_angles(const Eigen::Vector3f& d, float* elevation_rad,
                                    float* azimuth_rad) {
    const float horizontal_sq = d.x() * d.x() + d.y() * d.y();
    if (!(horizontal_sq > 1e-30f && horizontal_sq < 1e30f && std::fabs(d.z()) < 1e15f)) {
        return false;  // std::atan2 takes tiny, huge and not finite coordinates
    }
    *elevation_rad = range_image_internal::fast_atan2(d.z(), std::sqrt(horizontal_sq));
    *azimuth_rad = range_image_internal::fast_atan2(d.y(), d.x());
    return true;
}

inline bool RangeImage::clear_of_edges(float elevation_bins, float azimuth_bins, int* row,
                                       int* column) const {
    // A fast angle is within kFastAngleMarginRad of std::atan2's, and its subtraction and
    // division round by at most a few float ulps (the relative term): where both coordinates
    // are farther than that from a whole bin, std::atan2's fall in the same bins and compare the
    // same with any whole number of bins. Floors by truncation and a step down (no library call)
    // for coordinates below a million bins, as they are.
    if (!(std::fabs(elevation_bins) < 1e6f && std::fabs(azimuth_bins) < 1e6f)) return false;
    const auto floor_of = [](float v) {
        const int t = static_cast<int>(v);
        return t - (v < static_cast<float>(t));
    };
    const int el_floor = floor_of(elevation_bins);
    const int az_floor = floor_of(azimuth_bins);
    const float el_edge = std::min(elevation_bins - static_cast<float>(el_floor),
                                   static_cast<float>(el_floor + 1) - elevation_bins);
    const float az_edge = std::min(azimuth_bins - static_cast<float>(az_floor),
                                   static_cast<float>(az_floor + 1) - azimuth_bins);
    if (el_edge > fast_margin_bins_ + 1e-6f * std::fabs(elevation_bins) &&
        az_edge > fast_margin_bins_ + 1e-6f * std::fabs(azimuth_bins)) {
        *row = el_floor;
        *column = az_floor;
        return true;
    }
    return false;
}

RangeLookup RangeImage::nearest_around(const Eigen::Vector3f& direction_sensor,
                                       int radius_bins) const {
    if (radius_bins != window_radius_ || ranges_.empty()) {
        return nearest_around_bins(direction_sensor, radius_bins);
    }
    RangeLookup result;
    float el;
    int col;
    locate(direction_sensor, &el, &col);
    if (el < -static_cast<float>(radius_bins) || el >= static_cast<float>(rows_ + radius_bins)) {
        return result;
    }
    const int row = static_cast<int>(std::floor(el)) + radius_bins;  // a row of the window image
    col %= cols_;
    if (col < 0) col += cols_;
    const std::size_t bin = static_cast<std::size_t>(row) * cols_ + col;
    result.returns = window_returns_[bin];
    result.min_range_m = window_min_[bin];
    return result;
}

inline void RangeImage::locate(const Eigen::Vector3f& direction_sensor, float* elevation_bins,
                               int* column) const {
    // The free-space votes ask every image about hundreds of thousands of points, and std::atan2
    // (twice a point) was most of their time: the fast arctangent where its bins are certain
    // (clear_of_edges), std::atan2 elsewhere.
    float elevation_rad, azimuth_rad;
    if (fast_angles(direction_sensor, &elevation_rad, &azimuth_rad)) {
        // Multiplied by the inverse bin: one more rounding, within clear_of_edges' margin.
        const float el = (elevation_rad - elevation_min_rad_) * inverse_bin_rad_;
        int row;
        if (clear_of_edges(el, (azimuth_rad + kTwoPi / 2) * inverse_bin_rad_, &row, column)) {
            *elevation_bins = el;
            return;
        }
    }
    *elevation_bins = (elevation_of(direction_sensor) - elevation_min_rad_) / bin_rad_;
    *column = static_cast<int>((azimuth_of(direction_sensor) + kTwoPi / 2) / bin_rad_);
}

RangeLookup RangeImage::nearest_around_bins(const Eigen::Vector3f& direction_sensor,
                                            int radius_bins) const {
    RangeLookup result;
    if (ranges_.empty()) return result;
    const float el = (elevation_of(direction_sensor) - elevation_min_rad_) / bin_rad_;
    if (el < -static_cast<float>(radius_bins) || el >= static_cast<float>(rows_ + radius_bins)) {
        return result;
    }
    const int row = static_cast<int>(std::floor(el));
    const int col = static_cast<int>((azimuth_of(direction_sensor) + kTwoPi / 2) / bin_rad_);
    float nearest = 0.0f;
    for (int r = std::max(0, row - radius_bins); r <= std::min(rows_ - 1, row + radius_bins); ++r) {
        const float* line = ranges_.data() + static_cast<std::size_t>(r) * cols_;
        for (int dc = -radius_bins; dc <= radius_bins; ++dc) {
            int c = (col + dc) % cols_;
            if (c < 0) c += cols_;
            const float range = line[c];
            if (range == 0.0f) continue;
            ++result.returns;
            if (nearest == 0.0f || range < nearest) nearest = range;
        }
    }
    result.min_range_m = nearest;
    return result;
}

void RangeImage::prepare_window(int radius_bins) {
    window_radius_ = -1;
    window_min_.clear();
    window_returns_.clear();
    if (ranges_.empty() || radius_bins < 0 || radius_bins > kMaxWindowRadiusBins) return;
    const int r = radius_bins;
    const std::size_t cols = static_cast<std::size_t>(cols_);
    // Along each row first: the nearest return and the count over the columns col - r .. col + r,
    // wrapping around (a column met twice, in an image narrower than the window, counts twice,
    // as in nearest_around_bins()).
    std::vector<float> row_min(ranges_.size(), 0.0f);
    std::vector<std::uint16_t> row_returns(ranges_.size(), 0);
    tbb::parallel_for(0, rows_, [&](int row) {
        const float* line = ranges_.data() + static_cast<std::size_t>(row) * cols;
        for (int col = 0; col < cols_; ++col) {
            float nearest = 0.0f;
            std::uint16_t returns = 0;
            for (int dc = -r; dc <= r; ++dc) {
                int c = (col + dc) % cols_;
                if (c < 0) c += cols_;
                const float range = line[c];
                if (range == 0.0f) continue;
                ++returns;
                if (nearest == 0.0f || range < nearest) nearest = range;
            }
            row_min[static_cast<std::size_t>(row) * cols + col] = nearest;
            row_returns[static_cast<std::size_t>(row) * cols + col] = returns;
        }
    });
    // Then across the rows of the image within r of each window row.
    const int window_rows = rows_ + 2 * r;
    window_min_.assign(static_cast<std::size_t>(window_rows) * cols, 0.0f);
    window_returns_.assign(window_min_.size(), 0);
    tbb::parallel_for(0, window_rows, [&](int w) {
        const int centre = w - r;
        float* out_min = window_min_.data() + static_cast<std::size_t>(w) * cols;
        std::uint16_t* out_returns = window_returns_.data() + static_cast<std::size_t>(w) * cols;
        for (int row = std::max(0, centre - r); row <= std::min(rows_ - 1, centre + r); ++row) {
            const float* in_min = row_min.data() + static_cast<std::size_t>(row) * cols;
            const std::uint16_t* in_returns =
                row_returns.data() + static_cast<std::size_t>(row) * cols;
            for (std::size_t c = 0; c < cols; ++c) {
                out_returns[c] = static_cast<std::uint16_t>(out_returns[c] + in_returns[c]);
                const float range = in_min[c];
                if (range != 0.0f && (out_min[c] == 0.0f || range < out_min[c])) {
                    out_min[c] = range;
                }
            }
        }
    });
    window_radius_ = r;
}

}  // namespace shine
