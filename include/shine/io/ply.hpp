// PLY files: triangle meshes (reference and output meshes) and point clouds (scans).
//
// Reads ASCII, binary_little_endian and binary_big_endian PLY with any scalar property types;
// writes binary little-endian. Every failure names the file, the place (header line, body line for
// ascii, byte offset for binary) and the problem. Each reader has a parse_* twin that takes the
// file's bytes and the name to use in messages.
//
// Meshes far from the world origin (TriangleMesh::origin_world_m non-zero) keep float32 vertices
// in their local frame and carry the origin in the header, full double precision:
//   comment shine_origin_world_m 500000 5000000 0 (world = origin + vertex)
// Other programs (Blender, MeshLab) ignore the comment and show the mesh in the local frame, where
// float32 keeps millimetres; ShineVDB's reader restores origin_world_m from it.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string_view>
#include <vector>

#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/point_times.hpp"

namespace shine {

/// Reads a triangle mesh (vertex x y z; face vertex_indices or vertex_index, polygons
/// fan-triangulated, faces with fewer than 3 corners dropped; optional scalar face property
/// `observed`, copied to every triangle of its polygon as 0/1; vertex_rgb from scalar vertex
/// properties red, green and blue (all three; values clamped to 0..255), vertex_intensity from
/// `intensity`; origin_world_m from the shine_origin_world_m comment, else zero). Other
/// properties and elements are
/// skipped. A file without faces gives an empty triangle list. Throws IoError on a missing,
/// empty, truncated or malformed file, on element counts larger than the file can hold (checked
/// before allocating), on non-finite vertex coordinates and on out-of-range vertex indices.
TriangleMesh read_ply_mesh(const std::filesystem::path& path);

/// read_ply_mesh on bytes already in memory; `source` names them in messages.
TriangleMesh parse_ply_mesh(std::string_view data, const std::filesystem::path& source);

/// Writes a binary little-endian PLY atomically (temporary file + rename) from one buffer. Writes
/// the uchar `observed` face property when mesh.face_observed is non-empty, and the
/// shine_origin_world_m comment when mesh.origin_world_m is not zero, and the vertex properties
/// uchar red, green, blue and float intensity when mesh.vertex_rgb / vertex_intensity are
/// non-empty. Throws DataError if face_observed or a vertex attribute has the wrong size or a
/// triangle refers to a missing vertex.
void write_ply_mesh(const std::filesystem::path& path, const TriangleMesh& mesh);

/// Writes a mesh too large to hold in memory piece by piece, as the same binary PLY as
/// write_ply_mesh (without `observed`): vertices and triangles go to two temporary files beside
/// `path` as they come, and commit() writes the header and both parts into `path` atomically.
/// Without commit() (an exception on the way, say) nothing appears under `path`; the temporary
/// files are removed either way. Throws IoError naming `path` when a write fails.
class PlyMeshStreamWriter {
  public:
    /// With `copy`, every vertex and triangle added is also appended to it (which starts empty,
    /// at origin_world_m): the mesh as the file will hold it, for a caller that needs it next.
    PlyMeshStreamWriter(std::filesystem::path path, const Eigen::Vector3d& origin_world_m,
                        TriangleMesh* copy = nullptr);
    ~PlyMeshStreamWriter();
    PlyMeshStreamWriter(const PlyMeshStreamWriter&) = delete;
    PlyMeshStreamWriter& operator=(const PlyMeshStreamWriter&) = delete;

    /// Appends a vertex (in the frame of origin_world_m) and returns its index.
    std::int32_t add_vertex(const Eigen::Vector3f& vertex);
    /// Appends a triangle of vertices already added; throws DataError for an index out of range.
    void add_triangle(std::int32_t a, std::int32_t b, std::int32_t c);

    std::size_t num_vertices() const { return num_vertices_; }
    std::size_t num_triangles() const { return num_triangles_; }

    /// Writes `path`: header, vertices, triangles. Call once, after the last triangle.
    void commit();

  private:
    void check(const std::ostream& stream, const char* what) const;

    std::filesystem::path path_;
    Eigen::Vector3d origin_world_m_;
    std::filesystem::path vertex_path_;
    std::filesystem::path face_path_;
    std::ofstream vertices_;
    std::ofstream faces_;
    std::size_t num_vertices_ = 0;
    std::size_t num_triangles_ = 0;
    TriangleMesh* copy_ = nullptr;
};

/// Reads the vertex positions of a PLY point cloud (faces, if any, are ignored; NaN coordinates
/// are returned as stored, preprocess_scan filters them). Throws IoError as read_ply_mesh.
std::vector<Eigen::Vector3f> read_ply_points(const std::filesystem::path& path);

/// read_ply_points on bytes already in memory; `source` names them in messages.
std::vector<Eigen::Vector3f> parse_ply_points(std::string_view data,
                                              const std::filesystem::path& source);

/// Reads a PLY scan: the vertex positions as read_ply_points, and the per-point times of the
/// vertex element's first property named t, time, timestamp or offset_time (any scalar type;
/// unit and reference by point_times.hpp's rules, `stamp_s` the scan's stamp when it has one).
/// Without such a property point_time_s is empty. The intensity is the first vertex property
/// named intensity, reflectivity, reflectance, scalar_intensity or i (without case, so
/// CloudCompare's scalar_Intensity too; any scalar type, as float, never rescaled; empty when every
/// value is 0 or not finite; point_intensity.hpp). Throws IoError as read_ply_mesh, and for an
/// intensity property that is a list.
TimedPoints read_ply_scan(const std::filesystem::path& path,
                          std::optional<double> stamp_s = std::nullopt);

/// read_ply_scan on bytes already in memory; `source` names them in messages.
TimedPoints parse_ply_scan(std::string_view data, const std::filesystem::path& source,
                           std::optional<double> stamp_s = std::nullopt);

/// Writes points as a binary little-endian PLY point cloud, atomically.
void write_ply_points(const std::filesystem::path& path,
                      const std::vector<Eigen::Vector3f>& points);

/// Writes a scan with per-point times as a binary little-endian PLY, atomically: float x y z and
/// float `t`, seconds relative to the scan's pose (what read_ply_scan reads back). Throws
/// DataError if the counts differ.
void write_ply_scan(const std::filesystem::path& path, const std::vector<Eigen::Vector3f>& points,
                    const std::vector<double>& point_time_s);

}  // namespace shine
