// Closed triangle-mesh primitives for the street simulator, and their refinement to a maximum
// edge length.
//
// Every primitive is built coarse (a box is 12 triangles), closed and outward-oriented: each
// directed edge appears once and its reverse once, and the signed volume is positive. Then
// refine_to_max_edge() splits edges at their midpoints (longest-edge bisection, conforming, so the
// surface stays closed and no T-junctions appear) until no edge is longer than the limit.
// The fine tessellation matters for evaluation: completion is counted only over reference
// triangles that a simulated ray hit, so a triangle must be small compared to the ray spacing.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

#include "shine/geometry/triangle_mesh.hpp"

namespace shine::sim {

/// Axis-aligned box from `min_corner_m` to `max_corner_m` (12 triangles). Throws ConfigError if
/// any extent is not positive.
TriangleMesh make_box_mesh(const Eigen::Vector3f& min_corner_m,
                           const Eigen::Vector3f& max_corner_m);

/// Right prism: the simple polygon `polygon_ccw_m` (counter-clockwise, in the local x-y plane)
/// extruded along local +z from 0 to `height_m`; caps are ear-clipped. Throws ConfigError if the
/// polygon has fewer than 3 vertices, is clockwise, or the height is not positive.
TriangleMesh make_prism_mesh(const std::vector<Eigen::Vector2f>& polygon_ccw_m, float height_m);

/// Right prism over a rectilinear polygon (every edge parallel to x or y, counter-clockwise) from
/// z0_m to z1_m, tessellated directly on a grid whose cells have a diagonal of at most
/// `max_edge_m`: about half the triangles of refining a coarse prism by bisection. Closed and
/// outward. Throws ConfigError for a polygon that is not rectilinear, counter-clockwise and simple.
TriangleMesh make_grid_prism_mesh(const std::vector<Eigen::Vector2f>& polygon_ccw_m, float z0_m,
                                  float z1_m, float max_edge_m);

/// Closed cylinder along local +z from 0 to `height_m`, `segments` sides, fan caps.
TriangleMesh make_cylinder_mesh(float radius_m, float height_m, int segments);

/// Closed cylinder along local +z from 0 to `height_m` whose side is tessellated on a grid (cell
/// diagonal at most `max_edge_m`, at least 8 sides); cap spokes longer than `max_edge_m` still
/// need refine_to_max_edge().
TriangleMesh make_grid_cylinder_mesh(float radius_m, float height_m, float max_edge_m);

/// Closed ellipsoid centred at the origin: an icosahedron subdivided `subdivisions` times,
/// projected to the unit sphere and scaled by `radii_m`.
TriangleMesh make_ellipsoid_mesh(const Eigen::Vector3f& radii_m, int subdivisions);

/// Applies `T` to all vertices; reverses the winding if `T` mirrors (negative determinant) so that
/// normals stay outward.
void transform_mesh(TriangleMesh& mesh, const Eigen::Affine3f& T);

/// Appends `part` to `mesh` (vertex indices offset; face_observed is not touched).
void append_mesh(TriangleMesh& mesh, const TriangleMesh& part);

/// Splits triangles by conforming longest-edge bisection until no edge is longer than
/// `max_edge_m`. Keeps a closed surface closed and the orientation of every triangle; produces no
/// degenerate triangles from non-degenerate ones. Throws ConfigError if `max_edge_m` <= 0.
void refine_to_max_edge(TriangleMesh& mesh, float max_edge_m);

/// Length of the longest triangle edge of `mesh` (0 for an empty mesh).
float max_edge_length(const TriangleMesh& mesh);

}  // namespace shine::sim
