// sensor_msgs/PointCloud2 messages, serialised for ROS 1 or as CDR (ROS 2), decoded to points in
// the sensor frame and per-point times.
//
// Fields used: x y z (FLOAT32 or FLOAT64, required) and the first per-point time field found among
// t, time, timestamp, offset_time (point_times.hpp: integer datatypes are nanoseconds, FLOAT32 or
// FLOAT64 seconds unless they span more than 10 s in one cloud; an unknown datatype is a
// DataError). Point times are returned relative to the header stamp: values beyond 1e6 s (11.6
// days) are absolute and the stamp is subtracted; smaller values are already relative. The
// intensity is the first field named intensity, reflectivity, reflectance, scalar_intensity or i
// (without case; point_intensity.hpp), any numeric datatype, as float, never rescaled; another
// datatype or a count other than 1 is a DataError. Other fields (ring, ...) are skipped. Organised
// clouds (height > 1), padded point steps and padded rows are read; points are returned as stored,
// NaN included (organised clouds pad with NaN), as the KITTI/PLY/PCD readers do: preprocess_scan
// drops non-finite points. Big-endian point data is rejected.
#pragma once

#include <Eigen/Core>
#include <string>
#include <string_view>
#include <vector>

#include "shine/io/point_times.hpp"
#include "shine/io/recording.hpp"

namespace shine {

/// A decoded PointCloud2.
struct PointCloud2Scan {
    double stamp_s = 0.0;  ///< header.stamp in seconds
    std::string frame_id;
    std::vector<Eigen::Vector3f> points_sensor;
    /// Per-point time in seconds relative to stamp_s (empty without a time field).
    std::vector<double> point_time_s;
    std::string time_field;       ///< the field the times came from ("" without one)
    PointTimeFormat time_format;  ///< its type, unit and reference
    /// Per-point intensity as stored, one per point; empty without an intensity field or when
    /// every value is 0 or not finite (point_intensity.hpp).
    std::vector<float> intensity;
    std::string intensity_field;  ///< the field intensity came from ("" without one)
};

/// Decodes one serialised PointCloud2. `where` names the message in errors ("ROS 1 bag 'a.bag',
/// topic /points, message 3"). Throws IoError for truncated or inconsistent data (sizes that do
/// not fit, a big-endian cloud or CDR stream, an unknown CDR encapsulation) and DataError for a
/// cloud without x, y or z as FLOAT32/FLOAT64.
PointCloud2Scan decode_point_cloud2(std::string_view message, MessageEncoding encoding,
                                    const std::string& where);

/// Only the header stamp (seconds) of a serialised message with a std_msgs/Header first (as
/// PointCloud2 has); IoError naming `where` if the message is too short.
double decode_header_stamp_s(std::string_view message, MessageEncoding encoding,
                             const std::string& where);

/// Serialises a PointCloud2 of float32 x y z, float32 `intensity` (scan.intensity, 0 for every
/// point when it is empty) and, when `point_time_s` is not empty, float64 time `t` in seconds
/// relative to the stamp; CDR little-endian or ROS 1. Throws DataError when point_time_s or
/// intensity is neither empty nor one per point. Used by tests and by the fuzz seed writer;
/// `shine convert` writes KITTI, not messages.
std::string encode_point_cloud2(const PointCloud2Scan& scan, MessageEncoding encoding);

}  // namespace shine
