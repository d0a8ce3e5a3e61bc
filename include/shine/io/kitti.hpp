// KITTI odometry layout: velodyne/NNNNNN.bin scans, poses.txt, calib.txt.
//
// Each reader has a parse_* twin that takes the file's bytes and the name to use in messages
// (tests and fuzz targets use them; the read_* functions read the file and call them).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <filesystem>
#include <string_view>
#include <vector>

namespace shine {

/// Reads a KITTI .bin scan: little-endian float32 x y z intensity per point, sensor frame.
/// An empty file is a scan without returns and gives zero points. Throws IoError if the file is
/// missing or its size is not a multiple of 16 bytes (naming the byte offset of the partial
/// record). Points are returned as stored (NaN included: preprocess_scan filters). With
/// `intensity`, it receives the 4th column as stored, one per point, or is left empty when every
/// value is 0 or not finite (a .bin written without intensity; point_intensity.hpp).
std::vector<Eigen::Vector3f> read_kitti_bin(const std::filesystem::path& path,
                                            std::vector<float>* intensity = nullptr);

/// read_kitti_bin on bytes already in memory; `source` names them in messages.
std::vector<Eigen::Vector3f> parse_kitti_bin(std::string_view data,
                                             const std::filesystem::path& source,
                                             std::vector<float>* intensity = nullptr);

/// Writes a KITTI .bin scan atomically: `intensity` as the 4th column (empty: 0 for every
/// point). Throws DataError naming `path` if `intensity` is neither empty nor one per point.
void write_kitti_bin(const std::filesystem::path& path, const std::vector<Eigen::Vector3f>& points,
                     const std::vector<float>& intensity = {});

/// Reads a KITTI pose file: one pose per non-empty line, 12 numbers, row-major 3x4 [R|t].
/// Throws IoError naming the line on a wrong count, a non-number, a non-finite value or a rotation
/// that is not orthonormal (tolerance 1e-3), and IoError if the file is empty or has no pose.
std::vector<Eigen::Isometry3d> read_kitti_poses(const std::filesystem::path& path);

/// read_kitti_poses on text already in memory; `source` names it in messages.
std::vector<Eigen::Isometry3d> parse_kitti_poses(std::string_view text,
                                                 const std::filesystem::path& source);

/// Writes a KITTI pose file atomically (%.17g, so doubles round-trip exactly).
void write_kitti_poses(const std::filesystem::path& path,
                       const std::vector<Eigen::Isometry3d>& poses);

/// Reads the `Tr:` line (or `Tr_velo_to_cam:`) of a KITTI calib.txt (LiDAR-to-camera transform);
/// other lines (P0..P3) are ignored. Throws IoError naming the line for a malformed Tr line (as
/// read_kitti_poses) or a second one, and IoError if the file has no Tr line.
Eigen::Isometry3d read_kitti_calib_tr(const std::filesystem::path& path);

/// read_kitti_calib_tr on text already in memory; `source` names it in messages.
Eigen::Isometry3d parse_kitti_calib_tr(std::string_view text, const std::filesystem::path& source);

}  // namespace shine
