// Marching-cubes case table (Lorensen & Cline 1987), generated at first use rather than typed in.
//
// A cube has 8 corners numbered as in Bourke's and VDBFusion's tables, corner k at offset
// kCubeCorner[k] = (0,0,0) (1,0,0) (1,1,0) (0,1,0) (0,0,1) (1,0,1) (1,1,1) (0,1,1), and 12
// edges kCubeEdge[e] = {a, b}. A case is the 8-bit mask of the corners whose value is negative
// (inside, behind the surface). For every case the table lists the triangles of the surface
// inside the cube as triples of edge numbers (the surface crosses an edge at most once).
//
// How the table is built: on each of the six faces the sign pattern gives 0, 1 or 2 line
// segments between the crossed edges; on an ambiguous face (two diagonal negative corners) the
// segments cut off the negative corners, a rule that depends only on the face's four signs, so
// the two cubes sharing a face always agree and the mesh has no cracks. Each segment is oriented
// so that the positive side lies to its left seen from outside the cube; the segments then chain
// into closed loops around the negative region, and each loop (3 to 6 edges, not always planar)
// is fan-triangulated from the vertex whose fan faces the positive side best, so that no triangle
// lies flat in a cube face (checked for all cases in tests/test_tsdf_mesh.cpp). The triangles
// are therefore wound counter-clockwise seen from the positive side: the normal (b-a)x(c-a)
// points from negative to positive (for a TSDF, out of the surface into free space).
//
// Against the classic hand-written table: the same edges are crossed (so the same vertices), the
// polygons are the same except on ambiguous faces, and a polygon of more than three vertices may
// be split along a different diagonal.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

namespace shine {

/// Offsets of the 8 cube corners (x, y, z), Bourke's numbering.
inline constexpr int kCubeCorner[8][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0},
                                          {0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}};

/// The 12 cube edges as corner pairs {a, b}; a is the corner with the smaller coordinate along
/// the edge's axis.
inline constexpr int kCubeEdge[12][2] = {{0, 1}, {3, 2}, {4, 5}, {7, 6}, {0, 3}, {1, 2},
                                         {4, 7}, {5, 6}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};

/// Axis (0 = x, 1 = y, 2 = z) along which edge e runs.
inline constexpr int kCubeEdgeAxis[12] = {0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2, 2};

/// The triangles of one case, as edge numbers, wound so the normal points to the positive side.
struct MarchingCubesCase {
    std::uint16_t edge_mask = 0;                         ///< bit e set: edge e is crossed
    std::vector<std::array<std::uint8_t, 3>> triangles;  ///< edge triples
};

/// The 256 cases, indexed by the mask of negative corners (bit k: corner k is negative). Built
/// once, thread-safely, on first use.
const std::array<MarchingCubesCase, 256>& marching_cubes_table();

}  // namespace shine
