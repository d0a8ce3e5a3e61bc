#include "shine/render/lidar_model.hpp"

#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>

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
    const long half_bins = static_cast<long>(std::ceil(1.0 / bin)) + 1;
    std::vector<int> counts(std::size_t(2 * half_bins + 1), 0);
    for (const Eigen::Vector3d& u : units) {
        const long b = std::lround(std::floor(u.dot(axis) / bin));
        ++counts[std::size_t(std::clamp(b, -half_bins, half_bins) + half_bins)];
    }
    double sum = 0.0;
    for (const int n : counts) sum += double(n) * n;
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

/// Finer azimuth steps than this many columns per turn are not a LiDAR's.
constexpr int kMaxColumns = 32768;
/// More clusters than this are not sought (noise once the rings are taken).
constexpr std::size_t kMaxClusters = 512;
/// Share of azimuth sectors both halves of a split ring must see.
constexpr double kMinSharedAzimuths = 0.8;

/// The ring nearest to a point of elevation `elevation` (beam frame) whose distance from the spin
/// axis is 1 / `inv_radius` (0: a direction, seen far away): ring k is seen there at
/// atan(tan(elevation_k) + height_k * inv_radius). -1 if the point is more than half a ring
/// spacing above the top ring or below the bottom one.
int nearest_ring(const SphericalLidarModel& model, double elevation, double inv_radius) {
    const std::vector<double>& rings = model.elevations_rad;
    const std::size_t n = rings.size();
    if (n < 2) return -1;
    const double t = std::tan(elevation);
    // atan is monotonic: the nearest ring is the nearest seen above or the nearest seen below.
    int above = -1, below = -1;
    double t_above = std::numeric_limits<double>::infinity();
    double t_below = -std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < n; ++k) {
        const double h = model.beam_heights_m.empty() ? 0.0 : model.beam_heights_m[k];
        const double t_k = std::tan(rings[k]) + h * inv_radius;
        if (t_k > t) {
            if (t_k < t_above) t_above = t_k, above = int(k);
        } else if (t_k > t_below) {
            t_below = t_k, below = int(k);
        }
    }
    if (above < 0) {
        return elevation - std::atan(t_below) > 0.5 * (rings[0] - rings[1]) ? -1 : below;
    }
    if (below < 0) {
        return std::atan(t_above) - elevation > 0.5 * (rings[n - 2] - rings[n - 1]) ? -1 : above;
    }
    return std::atan(t_above) - elevation < elevation - std::atan(t_below) ? above : below;
}

/// Column of azimuth `azimuth` (beam frame).
int column_of(const SphericalLidarModel& model, double azimuth) {
    int c = static_cast<int>(std::floor((kPi - azimuth) / model.azimuth_step_rad()));
    c %= model.num_columns;
    return c < 0 ? c + model.num_columns : c;
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
    if (!(d.norm() > 0.0)) return false;
    const int r = nearest_ring(*this, std::atan2(d.z(), std::hypot(d.x(), d.y())), 0.0);
    if (r < 0) return false;
    row = r;
    col = column_of(*this, std::atan2(d.y(), d.x()));
    return true;
}

bool SphericalLidarModel::pixel_of_point(const Eigen::Vector3d& point_sensor, int& row,
                                         int& col) const {
    const Eigen::Vector3d d = R_sensor_beams.transpose() * point_sensor;
    const double radius = std::hypot(d.x(), d.y());
    if (!(radius > 0.0)) return pixel_of(point_sensor, row, col);
    const int r = nearest_ring(*this, std::atan2(d.z(), radius), 1.0 / radius);
    if (r < 0) return false;
    row = r;
    col = column_of(*this, std::atan2(d.y(), d.x()));
    return true;
}

namespace {

/// A point in a candidate beam frame: along the spin axis, distance from it, azimuth.
struct Ray {
    double z_m, radius_m, azimuth;
};

/// A ring found in a scan: its elevation from its beam height, and its median azimuth gap.
struct Ring {
    double elevation_rad, height_m, azimuth_step_rad;
};

/// The points about the spin axis `R_sensor_beams.col(2)`.
std::vector<Ray> rays_about(const std::vector<Eigen::Vector3d>& points,
                            const Eigen::Matrix3d& R_sensor_beams) {
    std::vector<Ray> rays;
    rays.reserve(points.size());
    for (const Eigen::Vector3d& p : points) {
        const Eigen::Vector3d d = R_sensor_beams.transpose() * p;
        rays.push_back({d.z(), std::hypot(d.x(), d.y()), std::atan2(d.y(), d.x())});
    }
    return rays;
}

/// Step 1: the axis around which the points' elevations are sharpest, coarse to fine (search step
/// and histogram bin shrink together).
Eigen::Vector3d search_spin_axis(const std::vector<Eigen::Vector3d>& units,
                                 const SphericalLidarConfig& config) {
    if (!(config.max_tilt_deg > 0.0)) return Eigen::Vector3d::UnitZ();
    std::vector<Eigen::Vector3d> sample;
    const std::size_t stride = std::max<std::size_t>(1, units.size() / config.max_points);
    for (std::size_t i = 0; i < units.size(); i += stride) sample.push_back(units[i]);
    double roll = 0.0, pitch = 0.0;
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
    return axis_of(roll, pitch);
}

/// Step 2 and 3: the rings about the rays' axis, each found in focus of its own beam height,
/// highest first.
std::vector<Ring> find_rings(const std::vector<Ray>& rays, const SphericalLidarConfig& config) {
    const int half_rows =
        config.max_beam_height_m > 0.0 && config.beam_height_step_m > 0.0
            ? static_cast<int>(config.max_beam_height_m / config.beam_height_step_m + 1e-9)
            : 0;
    const int rows = 2 * half_rows + 1;
    const auto height_of = [&](int row) { return (row - half_rows) * config.beam_height_step_m; };
    // Bins a quarter of the gap that ends a ring: such a gap is 4 empty bins, whatever the phase.
    const double bin_rad = 0.25 * config.min_ring_gap_deg * kDegToRad;
    const int bins = static_cast<int>(std::ceil(kPi / bin_rad)) + 1;
    const auto bin_of = [&](const Ray& ray, int row) {
        const double e = std::atan2(ray.z_m - height_of(row), ray.radius_m);
        return std::clamp(static_cast<int>(std::floor((e + 0.5 * kPi) / bin_rad)), 0, bins - 1);
    };
    std::vector<int> counts(std::size_t(rows) * bins, 0);
    const auto add_votes = [&](const std::vector<std::size_t>& which, int sign) {
        tbb::parallel_for(0, rows, [&](int row) {
            int* row_counts = counts.data() + std::size_t(row) * bins;
            for (const std::size_t i : which) row_counts[bin_of(rays[i], row)] += sign;
        });
    };
    std::vector<std::size_t> remaining(rays.size());
    for (std::size_t i = 0; i < rays.size(); ++i) remaining[i] = i;
    add_votes(remaining, +1);
    // A ring whose points lie at one range (the ground near the car) is sharp from many beam
    // heights; it keeps the one nearest the previous ring's (a block of lasers shares a height),
    // or the origin for the first: rows are searched in that order and ties keep the first.
    std::vector<int> row_order(rows);
    const auto order_rows_from = [&](int centre) {
        for (int row = 0; row < rows; ++row) row_order[row] = row;
        std::stable_sort(row_order.begin(), row_order.end(),
                         [&](int a, int b) { return std::abs(a - centre) < std::abs(b - centre); });
    };
    order_rows_from(half_rows);
    const int gap_bins = 4;
    struct Cluster {
        double height_m;
        std::vector<std::size_t> members;
    };
    std::vector<Cluster> clusters;
    int first_peak = 0;
    while (clusters.size() < kMaxClusters && !remaining.empty()) {
        int best = 0, best_row = 0, best_bin = 0;
        for (const int row : row_order) {
            const int* c = counts.data() + std::size_t(row) * bins;
            for (int b = 1; b + 1 < bins; ++b) {
                const int window = c[b - 1] + c[b] + c[b + 1];
                if (window > best) best = window, best_row = row, best_bin = b;
            }
        }
        if (clusters.empty()) first_peak = best;
        if (best == 0 || best < 0.25 * config.min_ring_share * first_peak) break;
        // The ring spans the peak's row until gap_bins empty bins on either side. A bin holding
        // under 1 % of the peak bin's count counts as empty: a thin ring's close points, a little
        // out of focus at this beam-height step, would bridge the gap to its neighbour.
        const int* c = counts.data() + std::size_t(best_row) * bins;
        const int peak_bin = std::max({c[best_bin - 1], c[best_bin], c[best_bin + 1]});
        const auto occupied = [&](int b) { return c[b] > 0 && 100 * c[b] >= peak_bin; };
        int lo = best_bin - 1, hi = best_bin + 1;
        for (int b = lo - 1, empty = 0; b >= 0 && empty < gap_bins; --b) {
            empty = occupied(b) ? 0 : empty + 1;
            if (occupied(b)) lo = b;
        }
        for (int b = hi + 1, empty = 0; b < bins && empty < gap_bins; ++b) {
            empty = occupied(b) ? 0 : empty + 1;
            if (occupied(b)) hi = b;
        }
        Cluster cluster{height_of(best_row), {}};
        std::vector<std::size_t> rest;
        for (const std::size_t i : remaining) {
            const int b = bin_of(rays[i], best_row);
            (b >= lo && b <= hi ? cluster.members : rest).push_back(i);
        }
        add_votes(cluster.members, -1);
        remaining.swap(rest);
        order_rows_from(best_row);
        clusters.push_back(std::move(cluster));
    }
    std::vector<double> sizes;
    for (const Cluster& cluster : clusters) sizes.push_back(double(cluster.members.size()));
    const double min_size = sizes.empty() ? 0.0 : config.min_ring_share * median(sizes);
    // Two rings that mostly hit the ground at one range are sharp from many beam heights, and the
    // points between them (walls, cars) can bridge the gap from the height chosen. A cluster is
    // split at its deepest dip when the dip holds under a quarter of the smaller side's peak and
    // both sides are ring-sized; a thick ring has no such dip.
    for (std::size_t k = 0; k < clusters.size(); ++k) {
        Cluster& cluster = clusters[k];
        const int row =
            static_cast<int>(std::lround(cluster.height_m / config.beam_height_step_m)) + half_rows;
        std::vector<int> hist(bins, 0);
        for (const std::size_t i : cluster.members) ++hist[bin_of(rays[i], row)];
        std::vector<int> smooth(bins, 0);
        for (int b = 1; b + 1 < bins; ++b) smooth[b] = hist[b - 1] + hist[b] + hist[b + 1];
        std::vector<int> below(bins + 1, 0);  // members in bins < b
        for (int b = 0; b < bins; ++b) below[b + 1] = below[b] + hist[b];
        std::vector<int> max_left(bins, 0), max_right(bins, 0);
        for (int b = 1; b < bins; ++b) max_left[b] = std::max(max_left[b - 1], smooth[b - 1]);
        for (int b = bins - 2; b >= 0; --b)
            max_right[b] = std::max(max_right[b + 1], smooth[b + 1]);
        int split = -1;
        double deepest = 0.25;
        const int total = below[bins];
        for (int b = 1; b + 1 < bins; ++b) {
            const int side_peak = std::min(max_left[b], max_right[b]);
            if (side_peak == 0) continue;
            const double depth = double(smooth[b]) / side_peak;
            if (depth >= deepest) continue;
            if (below[b] < min_size || total - below[b + 1] < min_size) continue;
            deepest = depth, split = b;
        }
        if (split < 0) continue;
        Cluster upper{cluster.height_m, {}};
        std::vector<std::size_t> lower;
        for (const std::size_t i : cluster.members) {
            (bin_of(rays[i], row) > split ? upper.members : lower).push_back(i);
        }
        // Two rings each go all around; a ring smeared by motion (a deskewed scan) is high on one
        // side and low on the other, so its halves see different azimuths.
        constexpr int kSectors = 360;
        const auto sectors_of = [&](const std::vector<std::size_t>& members) {
            std::vector<char> seen(kSectors, 0);
            for (const std::size_t i : members) {
                const int s = static_cast<int>((rays[i].azimuth + kPi) / (2.0 * kPi) * kSectors);
                seen[std::clamp(s, 0, kSectors - 1)] = 1;
            }
            return seen;
        };
        const std::vector<char> seen_upper = sectors_of(upper.members),
                                seen_lower = sectors_of(lower);
        int both = 0, n_upper = 0, n_lower = 0;
        for (int s = 0; s < kSectors; ++s) {
            both += seen_upper[s] && seen_lower[s];
            n_upper += seen_upper[s];
            n_lower += seen_lower[s];
        }
        if (both < kMinSharedAzimuths * std::min(n_upper, n_lower)) continue;
        cluster.members.swap(lower);
        clusters.push_back(std::move(upper));
        --k;  // the lower part may hold another ring
    }
    std::vector<Ring> rings;
    for (const Cluster& cluster : clusters) {
        if (double(cluster.members.size()) < min_size) continue;
        std::vector<double> elevations, azimuths;
        for (const std::size_t i : cluster.members) {
            elevations.push_back(std::atan2(rays[i].z_m - cluster.height_m, rays[i].radius_m));
            azimuths.push_back(rays[i].azimuth);
        }
        // 3. The azimuth step: gaps between successive azimuths within the ring; finer gaps than
        // any LiDAR's step are duplicated returns (or dual returns) and are ignored.
        std::sort(azimuths.begin(), azimuths.end());
        std::vector<double> gaps;
        for (std::size_t i = 1; i < azimuths.size(); ++i) {
            const double gap = azimuths[i] - azimuths[i - 1];
            if (gap > kPi / kMaxColumns) gaps.push_back(gap);
        }
        rings.push_back({median(elevations), cluster.height_m, gaps.empty() ? 0.0 : median(gaps)});
    }
    std::sort(rings.begin(), rings.end(),
              [](const Ring& a, const Ring& b) { return a.elevation_rad > b.elevation_rad; });
    return rings;
}

/// How many rays lie within `tolerance_rad` of the cone of the ring nearest to them: a wrong spin
/// axis or merged rings leave most points out of focus.
std::size_t points_in_focus(const std::vector<Ray>& rays, const std::vector<Ring>& rings,
                            double tolerance_rad) {
    SphericalLidarModel model;
    for (const Ring& ring : rings) {
        model.elevations_rad.push_back(ring.elevation_rad);
        model.beam_heights_m.push_back(ring.height_m);
    }
    std::size_t in_focus = 0;
    for (const Ray& ray : rays) {
        if (!(ray.radius_m > 0.0)) continue;
        const int k = nearest_ring(model, std::atan2(ray.z_m, ray.radius_m), 1.0 / ray.radius_m);
        if (k < 0) continue;
        const double e = std::atan2(ray.z_m - model.beam_heights_m[k], ray.radius_m);
        in_focus += std::abs(e - model.elevations_rad[k]) <= tolerance_rad;
    }
    return in_focus;
}

}  // namespace

SphericalLidarModel infer_spherical_lidar(const std::vector<Eigen::Vector3f>& points_sensor,
                                          const SphericalLidarConfig& config) {
    std::vector<Eigen::Vector3d> points, units;
    for (const Eigen::Vector3f& p : points_sensor) {
        const Eigen::Vector3d q = p.cast<double>();
        const double r = q.norm();
        if (q.allFinite() && r >= config.min_range_m && r > 0.0) {
            points.push_back(q);
            units.push_back(q / r);
        }
    }
    if (units.size() < 16) {
        throw DataError("cannot infer the LiDAR's beam layout: only " +
                        std::to_string(units.size()) + " points are at least " +
                        std::to_string(config.min_range_m) + " m away");
    }
    // The axis search scores unit directions, which beam heights smear by h / r_xy (over a degree
    // within 10 m on an HDL-64E): it can settle a tenth of a degree off an untilted sensor's z and
    // merge rings there. So the sensor's z is a candidate too, and the axis kept is the one whose
    // rings hold the most points in focus.
    std::vector<Eigen::Vector3d> axes = {search_spin_axis(units, config)};
    if (axes.front() != Eigen::Vector3d::UnitZ()) axes.push_back(Eigen::Vector3d::UnitZ());
    SphericalLidarModel model;
    std::vector<Ring> rings;
    std::size_t best_in_focus = 0;
    const double tolerance_rad = config.focus_tolerance_deg * kDegToRad;
    for (const Eigen::Vector3d& axis : axes) {
        const Eigen::Matrix3d R_sensor_beams = frame_with_z(axis);
        const std::vector<Ray> rays = rays_about(points, R_sensor_beams);
        std::vector<Ring> found = find_rings(rays, config);
        const std::size_t in_focus = points_in_focus(rays, found, tolerance_rad);
        // Ties keep the first candidate: the result does not depend on the order of evaluation.
        if (rings.empty() || in_focus > best_in_focus) {
            best_in_focus = in_focus;
            rings = std::move(found);
            model.R_sensor_beams = R_sensor_beams;
        }
    }
    if (rings.size() < 2) {
        throw DataError("cannot infer the LiDAR's beam layout: the elevations of " +
                        std::to_string(units.size()) + " points form " +
                        std::to_string(rings.size()) +
                        " ring(s); a spinning LiDAR's scan has several");
    }
    std::vector<double> steps;
    for (const Ring& ring : rings) {
        model.elevations_rad.push_back(ring.elevation_rad);
        model.beam_heights_m.push_back(ring.height_m);
        if (ring.azimuth_step_rad > 0.0) steps.push_back(ring.azimuth_step_rad);
    }
    const double step = steps.empty() ? 0.0 : median(steps);
    model.num_columns = step > 0.0 ? static_cast<int>(std::lround(2.0 * kPi / step)) : 0;
    if (model.num_columns < 8 || model.num_columns > kMaxColumns) {
        throw DataError(
            "cannot infer the LiDAR's azimuth step: " + std::to_string(model.num_columns) +
            " columns per turn found in " + std::to_string(rings.size()) +
            " rings (expected 8 to " + std::to_string(kMaxColumns) + ")");
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
        if (!model.pixel_of_point(q, row, col)) continue;
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
