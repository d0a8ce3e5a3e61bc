// PCD (Point Cloud Library) files: ascii, binary and binary_compressed.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <string_view>
#include <vector>

#include "shine/io/point_times.hpp"

namespace shine {

/// Reads the x y z fields of a PCD file (any field order, F4 or F8 coordinates, other fields
/// skipped). Throws IoError naming the file and the place (header line, data line for ascii,
/// byte offset for binary) on a malformed header, missing x/y/z fields, a point count the data
/// cannot hold (checked before allocating), truncated data or a corrupt LZF block. Binary data is
/// read as little-endian (what PCL writes on every common platform). NaN points (PCL's "no
/// return") are returned as stored; preprocess_scan decides what happens to them.
std::vector<Eigen::Vector3f> read_pcd_points(const std::filesystem::path& path);

/// read_pcd_points on bytes already in memory; `source` names them in messages.
std::vector<Eigen::Vector3f> parse_pcd_points(std::string_view data,
                                              const std::filesystem::path& source);

/// Reads a PCD scan: the points as read_pcd_points, and the per-point times of the first field
/// named t, time, timestamp or offset_time with COUNT 1 (any TYPE and SIZE; unit and reference by
/// point_times.hpp's rules, `stamp_s` the scan's stamp when it has one). Without such a field
/// point_time_s is empty. The intensity is the first field named intensity, reflectivity,
/// reflectance, scalar_intensity or i (without case; any TYPE, as float, never rescaled; empty
/// when every value is 0 or not finite; point_intensity.hpp). Throws IoError as read_pcd_points,
/// and for an intensity field with COUNT other than 1 or TYPE F of SIZE other than 4 or 8.
TimedPoints read_pcd_scan(const std::filesystem::path& path,
                          std::optional<double> stamp_s = std::nullopt);

/// read_pcd_scan on bytes already in memory; `source` names them in messages.
TimedPoints parse_pcd_scan(std::string_view data, const std::filesystem::path& source,
                           std::optional<double> stamp_s = std::nullopt);

/// Writes x y z as a binary PCD atomically.
void write_pcd_points(const std::filesystem::path& path,
                      const std::vector<Eigen::Vector3f>& points);

}  // namespace shine
