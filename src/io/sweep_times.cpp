// Per-point times of a spinning LiDAR's sweep from the points' azimuths.
#include "shine/io/sweep_times.hpp"

#include <cmath>
#include <cstdio>
#include <limits>

#include "shine/core/error.hpp"

namespace shine {

const char* to_string(SweepDirection direction) {
    return direction == SweepDirection::kClockwise ? "clockwise" : "counterclockwise";
}

SweepDirection parse_sweep_direction(const std::string& text, const std::string& key) {
    if (text == "clockwise" || text == "cw") return SweepDirection::kClockwise;
    if (text == "counterclockwise" || text == "ccw") return SweepDirection::kCounterClockwise;
    throw ConfigError(key +
                      " must be 'clockwise' or 'counterclockwise' (as seen from above), got '" +
                      text + "'");
}

std::string SweepTimeModel::describe() const {
    char text[160];
    std::snprintf(text, sizeof(text),
                  "%s from azimuth %.1f deg, pose at azimuth %.1f deg, %.3f s a turn",
                  to_string(direction), start_azimuth_deg, pose_azimuth_deg, sweep_period_s);
    return text;
}

namespace {

constexpr double kDegPerRad = 180.0 / 3.14159265358979323846;

/// The phase (degrees in [0, 360)) of `azimuth_deg` in a sweep starting at `start_deg`.
double phase_deg(double azimuth_deg, double start_deg, double sign) {
    double phase = std::fmod(sign * (start_deg - azimuth_deg), 360.0);
    if (phase < 0.0) phase += 360.0;
    return phase;
}

}  // namespace

std::vector<double> sweep_point_times_s(const std::vector<Eigen::Vector3f>& points_sensor,
                                        const SweepTimeModel& model) {
    if (!(model.sweep_period_s > 0.0) || !std::isfinite(model.sweep_period_s)) {
        throw ConfigError("the sweep period must be positive (seconds of one turn, 0.1 at 10 Hz)");
    }
    if (!std::isfinite(model.start_azimuth_deg) || !std::isfinite(model.pose_azimuth_deg)) {
        throw ConfigError("the sweep's start and pose azimuths must be finite (degrees)");
    }
    const double sign = model.direction == SweepDirection::kClockwise ? 1.0 : -1.0;
    const double pose_phase = phase_deg(model.pose_azimuth_deg, model.start_azimuth_deg, sign);
    const double seconds_per_deg = model.sweep_period_s / 360.0;
    std::vector<double> times_s(points_sensor.size(), std::numeric_limits<double>::quiet_NaN());
    for (std::size_t i = 0; i < points_sensor.size(); ++i) {
        const Eigen::Vector3f& p = points_sensor[i];
        if (!p.allFinite()) continue;
        if (p.x() == 0.0f && p.y() == 0.0f) {  // on the spin axis: no azimuth, no motion to undo
            times_s[i] = 0.0;
            continue;
        }
        const double azimuth_deg =
            std::atan2(static_cast<double>(p.y()), static_cast<double>(p.x())) * kDegPerRad;
        times_s[i] =
            (phase_deg(azimuth_deg, model.start_azimuth_deg, sign) - pose_phase) * seconds_per_deg;
    }
    return times_s;
}

}  // namespace shine
