// PLY files: triangle meshes (reference and output meshes) and point clouds (scans).
//
// Reads ASCII, binary_little_endian and binary_big_endian PLY with any scalar property types;
// writes binary little-endian. Every failure names the file, the header line or byte offset, and
// the problem.
#pragma once

#include <Eigen/Core>
#include <filesystem>
#include <vector>

#include "shine/geometry/triangle_mesh.hpp"

namespace shine {

/// Reads a triangle mesh (vertex x y z; face vertex_indices or vertex_index, polygons
/// fan-triangulated, faces with fewer than 3 corners dropped; optional scalar face property
/// `observed`, copied to every triangle of its polygon as 0/1). Other properties and elements are
/// skipped. A file without faces gives an empty triangle list. Throws IoError on a missing,
/// empty, truncated or malformed file, on element counts larger than the file can hold (checked
/// before allocating) and on out-of-range vertex indices.
TriangleMesh read_ply_mesh(const std::filesystem::path& path);

/// Writes a binary little-endian PLY atomically (temporary file + rename) from one buffer. Writes
/// the uchar `observed` face property when mesh.face_observed is non-empty. Throws DataError if
/// face_observed has the wrong size or a triangle refers to a missing vertex.
void write_ply_mesh(const std::filesystem::path& path, const TriangleMesh& mesh);

/// Reads the vertex positions of a PLY point cloud (faces, if any, are ignored).
std::vector<Eigen::Vector3f> read_ply_points(const std::filesystem::path& path);

/// Writes points as a binary little-endian PLY point cloud, atomically.
void write_ply_points(const std::filesystem::path& path,
                      const std::vector<Eigen::Vector3f>& points);

}  // namespace shine
