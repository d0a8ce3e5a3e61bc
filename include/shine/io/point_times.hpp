// Per-point times of a scan as stored in a file or message, turned into seconds relative to the
// scan's reference time -- the one rule every reader (PLY, PCD, PointCloud2) applies.
//
// Field: the first of `t`, `time`, `timestamp`, `offset_time` the scan has (Ouster `t`, Velodyne
// `time`, Hesai / RoboSense `timestamp`, Livox `offset_time`).
// Unit: integer types are nanoseconds (Ouster, Livox); floating-point values are seconds, unless
// they span more than kMaxSweepSpanS (10 s) within the one scan -- no sweep lasts that long, a
// sweep in nanoseconds spans 10^7 - 10^8 -- in which case they are nanoseconds too.
// Reference: values whose largest magnitude (in seconds) exceeds kAbsoluteTimeS (10^6 s, 11.6
// days) are absolute times (seconds or nanoseconds since an epoch): the scan's stamp is
// subtracted when it has one (a recording's header stamp), else the earliest point's time, so
// that t = 0 is the start of the sweep. Smaller values are already relative to the scan: t = 0 is
// the instant of the scan's pose (for most drivers the start of the sweep).
// Deskewing (odometry/scan_deskew.hpp) assumes that the scan's pose belongs to t = 0.
#pragma once

#include <Eigen/Core>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace shine {

/// How a scan's per-point times were read: which field, in which unit, relative to what.
struct PointTimeFormat {
    std::string field;          ///< the field the times came from ("" without one)
    std::string type;           ///< its type as the file names it ("float32", "uint32", "F4", ...)
    bool nanoseconds = false;   ///< the stored values were nanoseconds (else seconds)
    bool absolute = false;      ///< the stored values were absolute times
    double subtracted_s = 0.0;  ///< what was subtracted from absolute times (stamp or earliest)
    bool from_stamp = false;    ///< subtracted_s is the scan's stamp (else the earliest point)

    /// "field 't' (float32): seconds, relative to the scan" -- for logs and stats.json.
    std::string describe() const;
};

/// Points of one scan in the sensor frame with their times and intensities, as the scan readers
/// return them.
struct TimedPoints {
    std::vector<Eigen::Vector3f> points_sensor;
    /// Seconds relative to the scan's reference time, one per point; empty without a time field.
    std::vector<double> point_time_s;
    PointTimeFormat time_format;  ///< how point_time_s was read (field "" without one)
    /// Per-point intensity as stored, one per point; empty without one (point_intensity.hpp).
    std::vector<float> intensity;
    std::string intensity_field;  ///< the field intensity came from ("" without one)
};

/// Stored values span at most this many seconds within one scan (else they are nanoseconds).
constexpr double kMaxSweepSpanS = 10.0;
/// Times beyond this many seconds are absolute (since an epoch), not relative to the scan.
constexpr double kAbsoluteTimeS = 1e6;

/// The names read as a per-point time, in order of preference: t, time, timestamp, offset_time.
const std::vector<std::string_view>& point_time_field_names();

/// Index into `field_names` of the per-point time field (the first name of
/// point_time_field_names() present), or -1 if there is none.
int find_point_time_field(const std::vector<std::string>& field_names);

/// The stored values `raw` of one scan (one per point, NaN allowed and kept) as seconds relative
/// to the scan's reference time, by the rules of the file comment. `integer_type`: the field has
/// an integer type (nanoseconds). `stamp_s`: the scan's stamp when it has one. Fills `format`
/// (field and type are left as the caller set them).
std::vector<double> point_times_relative_s(const std::vector<double>& raw, bool integer_type,
                                           std::optional<double> stamp_s, PointTimeFormat* format);

}  // namespace shine
