// Per-point time fields: name, unit and reference detection.
#include "shine/io/point_times.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

namespace shine {

std::string PointTimeFormat::describe() const {
    if (field.empty()) return "no per-point time";
    if (field == "azimuth") return "from the azimuth, " + type;  // sweep_times.hpp
    std::string text = "field '" + field + "'";
    if (!type.empty()) text += " (" + type + ")";
    text += nanoseconds ? ": nanoseconds" : ": seconds";
    if (!absolute) return text + ", relative to the scan (t = 0 at the scan's pose)";
    char number[64];
    std::snprintf(number, sizeof(number), "%.9f", subtracted_s);
    return text + ", absolute; made relative to " +
           (from_stamp ? std::string("the scan's stamp ") : std::string("the earliest point, ")) +
           number + " s";
}

const std::vector<std::string_view>& point_time_field_names() {
    static const std::vector<std::string_view> names = {"t", "time", "timestamp", "offset_time"};
    return names;
}

int find_point_time_field(const std::vector<std::string>& field_names) {
    for (const std::string_view name : point_time_field_names()) {
        for (std::size_t i = 0; i < field_names.size(); ++i) {
            if (field_names[i] == name) return static_cast<int>(i);
        }
    }
    return -1;
}

std::vector<double> point_times_relative_s(const std::vector<double>& raw, bool integer_type,
                                           std::optional<double> stamp_s, PointTimeFormat* format) {
    double lo = std::numeric_limits<double>::infinity();
    double hi = -std::numeric_limits<double>::infinity();
    for (const double v : raw) {
        if (!std::isfinite(v)) continue;
        lo = std::min(lo, v);
        hi = std::max(hi, v);
    }
    const bool any = lo <= hi;
    const bool nanoseconds = integer_type || (any && hi - lo > kMaxSweepSpanS);
    const double scale = nanoseconds ? 1e-9 : 1.0;
    const double largest_s = any ? std::max(std::abs(lo), std::abs(hi)) * scale : 0.0;
    const bool absolute = largest_s > kAbsoluteTimeS;
    double offset_s = 0.0;
    bool from_stamp = false;
    if (absolute) {
        from_stamp = stamp_s.has_value();
        offset_s = from_stamp ? *stamp_s : lo * scale;
    }
    std::vector<double> out(raw.size());
    if (absolute && !from_stamp) {
        // Subtract in the stored unit first: absolute nanoseconds (~1.7e18) lose their last digits
        // once scaled, their difference to the earliest point does not.
        for (std::size_t i = 0; i < raw.size(); ++i) out[i] = (raw[i] - lo) * scale;
    } else {
        for (std::size_t i = 0; i < raw.size(); ++i) out[i] = raw[i] * scale - offset_s;
    }
    if (format) {
        format->nanoseconds = nanoseconds;
        format->absolute = absolute;
        format->subtracted_s = offset_s;
        format->from_stamp = from_stamp;
    }
    return out;
}

}  // namespace shine
