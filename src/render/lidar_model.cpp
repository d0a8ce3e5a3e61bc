#include "shine/render/lidar_model.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_map>

#include "shine/core/error.hpp"

namespace shine {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;

/// The spin axis tilted by `roll` about x, then `pitch` about y (radians).
Eigen::Vector3d axis_of(double roll, double pitch) {
    return Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()) *
           (Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) * Eigen::Vector3d::UnitZ());
}

/// Sharpness of the points' elevations about `axis`: sum of squared counts of a histogram of
/// sin(elevation) with bins `bin` wide. Rings make tall, narrow peaks; a wrong axis smears them.
double sharpness(const std::vector<Eigen::Vector3d>& units, const Eigen::Vector3d& axis,
                 double bin) {
    std::unordered_map<long, int> counts;
    counts.reserve(units.size());
    for (const Eigen::Vector3d& u : units) ++counts[std::lround(std::floor(u.dot(axis) / bin))];
    double sum = 0.0;
    for (const auto& [key, n] : counts) sum += double(n) * n;
    return sum;
}

/// Frame whose z is `axis`, turned as little as possible from the sensor frame.
Eigen::Matrix3d frame_with_z(const Eigen::Vector3d& axis) {
    return Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), axis).toRotationMatrix();
}

double median(std::vector<double> v) {
    const std::size_t mid = v.size() / 2;
    std::nth_element(v.begin(), v.begin() + mid, v.end());
    return v[mid];
}

}  // namespace

double SphericalLidarModel::azimuth_step_rad() const { return 2.0 * kPi / num_columns; }

double SphericalLidarModel::tilt_deg() const {
    return std::acos(std::clamp(R_sensor_beams(2, 2), -1.0, 1.0)) / kDegToRad;
}

Eigen::Vector3d SphericalLidarModel::direction_sensor(int row, int col) const {
    const double elevation = elevations_rad.at(row);
    const double azimuth = kPi - (col + 0.5) * azimuth_step_rad();
    const Eigen::Vector3d beams(std::cos(elevation) * std::cos(azimuth),
                                std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
    return R_sensor_beams * beams;
}

bool SphericalLidarModel::pixel_of(const Eigen::Vector3d& direction_sensor, int& row,
                                   int& col) const {
    const Eigen::Vector3d d = R_sensor_beams.transpose() * direction_sensor;
    const double norm = d.norm();
    if (!(norm > 0.0) || elevations_rad.size() < 2) return false;
    const double elevation = std::asin(std::clamp(d.z() / norm, -1.0, 1.0));
    // elevations_rad is descending: find the nearest ring.
    const auto it = std::lower_bound(elevations_rad.begin(), elevations_rad.end(), elevation,
                                     [](double ring, double e) { return ring > e; });
    std::size_t r = std::size_t(it - elevations_rad.begin());
    const std::size_t n = elevations_rad.size();
    if (r == 0) {
        if (elevation - elevations_rad[0] > 0.5 * (elevations_rad[0] - elevations_rad[1])) {
            return false;
        }
    } else if (r == n) {
        r = n - 1;
        if (elevations_rad[n - 1] - elevation >
            0.5 * (elevations_rad[n - 2] - elevations_rad[n - 1])) {
            return false;
        }
    } else if (elevations_rad[r - 1] - elevation < elevation - elevations_rad[r]) {
        r -= 1;
    }
    row = static_cast<int>(r);
    const double azimuth = std::atan2(d.y(), d.x());
    int c = static_cast<int>(std::floor((kPi - azimuth) / azimuth_step_rad()));
    c %= num_columns;
    if (c < 0) c += num_columns;
    col = c;
    return true;
}

SphericalLidarModel infer_spherical_lidar(const std::vector<Eigen::Vector3f>& points_sensor,
                                          const SphericalLidarConfig& config) {
    std::vector<Eigen::Vector3d> units;
    for (const Eigen::Vector3f& p : points_sensor) {
        const Eigen::Vector3d q = p.cast<double>();
        const double r = q.norm();
        if (q.allFinite() && r >= config.min_range_m && r > 0.0) units.push_back(q / r);
    }
    if (units.size() < 16) {
        throw DataError("cannot infer the LiDAR's beam layout: only " +
                        std::to_string(units.size()) + " points are at least " +
                        std::to_string(config.min_range_m) + " m away");
    }

    // 1. The spin axis, coarse to fine (search step and histogram bin shrink together).
    std::vector<Eigen::Vector3d> sample;
    const std::size_t stride = std::max<std::size_t>(1, units.size() / config.max_points);
    for (std::size_t i = 0; i < units.size(); i += stride) sample.push_back(units[i]);
    double roll = 0.0, pitch = 0.0;
    if (config.max_tilt_deg > 0.0) {
        double half_range = config.max_tilt_deg * kDegToRad;
        double step = 1.0 * kDegToRad;
        for (int stage = 0; stage < 3; ++stage) {
            const int n = static_cast<int>(std::ceil(half_range / step));
            const int side = 2 * n + 1;
            const double bin = std::max(step, 0.01 * kDegToRad);
            std::vector<double> scores(std::size_t(side) * side);
            tbb::parallel_for(0, side * side, [&](int k) {
                const double a = roll + (k / side - n) * step;
                const double b = pitch + (k % side - n) * step;
                scores[k] = sharpness(sample, axis_of(a, b), bin);
            });
            // First maximum in a fixed order: the result does not depend on the thread count.
            const int best = int(std::max_element(scores.begin(), scores.end()) - scores.begin());
            roll += (best / side - n) * step;
            pitch += (best % side - n) * step;
            half_range = 1.5 * step;
            step /= 10.0;
        }
    }
    SphericalLidarModel model;
    model.R_sensor_beams = frame_with_z(axis_of(roll, pitch));

    // 2. Rings: clusters of sorted elevations.
    struct Ray {
        double elevation, azimuth;
    };
    std::vector<Ray> rays;
    rays.reserve(units.size());
    for (const Eigen::Vector3d& u : units) {
        const Eigen::Vector3d d = model.R_sensor_beams.transpose() * u;
        rays.push_back({std::asin(std::clamp(d.z(), -1.0, 1.0)), std::atan2(d.y(), d.x())});
    }
    std::sort(rays.begin(), rays.end(),
              [](const Ray& a, const Ray& b) { return a.elevation < b.elevation; });
    const double gap = config.min_ring_gap_deg * kDegToRad;
    std::vector<std::pair<std::size_t, std::size_t>> clusters;  // [first, last)
    std::size_t first = 0;
    for (std::size_t i = 1; i <= rays.size(); ++i) {
        if (i == rays.size() || rays[i].elevation - rays[i - 1].elevation > gap) {
            clusters.emplace_back(first, i);
            first = i;
        }
    }
    std::vector<double> sizes;
    for (const auto& [a, b] : clusters) sizes.push_back(double(b - a));
    const double min_size = config.min_ring_share * median(sizes);
    std::vector<double> azimuth_gaps;
    for (const auto& [a, b] : clusters) {
        if (double(b - a) < min_size) continue;
        model.elevations_rad.push_back(rays[a + (b - a) / 2].elevation);
        // 3. Azimuth gaps within the ring.
        std::vector<double> azimuths;
        for (std::size_t i = a; i < b; ++i) azimuths.push_back(rays[i].azimuth);
        std::sort(azimuths.begin(), azimuths.end());
        for (std::size_t i = 1; i < azimuths.size(); ++i) {
            const double d = azimuths[i] - azimuths[i - 1];
            if (d > 1e-9) azimuth_gaps.push_back(d);
        }
    }
    std::reverse(model.elevations_rad.begin(), model.elevations_rad.end());
    if (model.elevations_rad.size() < 2) {
        throw DataError("cannot infer the LiDAR's beam layout: the elevations of " +
                        std::to_string(units.size()) + " points form " +
                        std::to_string(model.elevations_rad.size()) +
                        " ring(s); a spinning LiDAR's scan has several");
    }
    const double step = azimuth_gaps.empty() ? 0.0 : median(azimuth_gaps);
    model.num_columns = step > 0.0 ? static_cast<int>(std::lround(2.0 * kPi / step)) : 0;
    if (model.num_columns < 8 || model.num_columns > 32768) {
        throw DataError(
            "cannot infer the LiDAR's azimuth step: " + std::to_string(model.num_columns) +
            " columns per turn found (expected 8 to 32768)");
    }
    return model;
}

PixelRays scan_pixel_rays(const SphericalLidarModel& model,
                          const std::vector<Eigen::Vector3f>& points_sensor, double min_range_m,
                          double max_range_m) {
    PixelRays rays;
    rays.width = model.width();
    rays.height = model.height();
    rays.directions_sensor.resize(rays.num_pixels());
    rays.measured_range_m.assign(rays.num_pixels(), std::numeric_limits<float>::quiet_NaN());
    for (int row = 0; row < rays.height; ++row) {
        for (int col = 0; col < rays.width; ++col) {
            rays.directions_sensor[std::size_t(row) * rays.width + col] =
                model.direction_sensor(row, col);
        }
    }
    for (const Eigen::Vector3f& p : points_sensor) {
        const Eigen::Vector3d q = p.cast<double>();
        const double range_m = q.norm();
        if (!q.allFinite() || !(range_m >= min_range_m && range_m <= max_range_m) ||
            range_m == 0.0) {
            continue;
        }
        int row = 0, col = 0;
        if (!model.pixel_of(q, row, col)) continue;
        const std::size_t i = std::size_t(row) * rays.width + col;
        float& measured = rays.measured_range_m[i];
        if (std::isnan(measured) || range_m < measured) {
            measured = static_cast<float>(range_m);
            rays.directions_sensor[i] = q / range_m;
        }
    }
    return rays;
}

}  // namespace shine
