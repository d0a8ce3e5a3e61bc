// KITTI odometry layout: velodyne/NNNNNN.bin scans, poses.txt, calib.txt.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <filesystem>
#include <vector>

namespace shine {

/// Reads a KITTI .bin scan: little-endian float32 x y z intensity per point, sensor frame.
/// Throws IoError if the file is missing, empty or its size is not a multiple of 16 bytes.
/// Points are returned as stored (no filtering); intensities are discarded.
std::vector<Eigen::Vector3f> read_kitti_bin(const std::filesystem::path& path);

/// Writes a KITTI .bin scan atomically (intensity written as 0).
void write_kitti_bin(const std::filesystem::path& path, const std::vector<Eigen::Vector3f>& points);

/// Reads a KITTI pose file: one pose per non-empty line, 12 numbers, row-major 3x4 [R|t].
/// Throws IoError naming the line on a wrong count, a non-number, a non-finite value or a rotation
/// that is not orthonormal (tolerance 1e-3).
std::vector<Eigen::Isometry3d> read_kitti_poses(const std::filesystem::path& path);

/// Writes a KITTI pose file atomically (%.17g, so doubles round-trip exactly).
void write_kitti_poses(const std::filesystem::path& path,
                       const std::vector<Eigen::Isometry3d>& poses);

/// Reads the `Tr:` line (or `Tr_velo_to_cam:`) of a KITTI calib.txt (LiDAR-to-camera transform);
/// other lines (P0..P3) are ignored. Throws IoError if the file has no valid Tr line.
Eigen::Isometry3d read_kitti_calib_tr(const std::filesystem::path& path);

}  // namespace shine
