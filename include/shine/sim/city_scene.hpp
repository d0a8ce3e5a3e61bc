// The geometry of a CityRoute: every street block built by make_street_scene and moved into place,
// every junction's ground, in one mesh whose blocks (one per street block and per junction) are
// what BlockRayCaster casts against.
#pragma once

#include <vector>

#include "shine/geometry/triangle_mesh.hpp"
#include "shine/sim/block_ray_caster.hpp"
#include "shine/sim/city_route.hpp"
#include "shine/sim/street_scene.hpp"

namespace shine::sim {

/// The city's mesh and parts, and its triangle blocks.
struct CityScene {
    StreetScene scene;  ///< all streets, then all junctions; object indices unique over the city
    std::vector<TriangleBlock> blocks;  ///< route.segments in order, then route.junctions
};

/// Builds the streets and junctions in parallel (TBB); deterministic for a route (independent of
/// the thread count). Shows a progress line if `show_progress`.
CityScene make_city_scene(const CityRoute& route, bool show_progress = false);

/// Ground of one junction: an open height field over junction.area_m, z = 0 on the road (the
/// crossing and the arms towards existing streets) and the curb height elsewhere, joined by
/// vertical curb faces; normals point up or towards the road, no edge is longer than the street's
/// max_edge_length_m. Its borders meet the streets' grounds on the same lines and heights.
TriangleMesh make_junction_ground(const CityRoute& route, const Junction& junction);

}  // namespace shine::sim
