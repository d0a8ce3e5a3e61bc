// A deterministic procedural street: the reference geometry of the bundled example data.
//
// The street runs along world +x; world z is up; the road surface is z = 0. Across the street
// (y) lie: a road, curbs (a vertical step up to the sidewalks), sidewalks, and lots holding
// buildings of varied footprint, height and shape (boxes, L-shapes, setbacks, gable roofs, roof
// boxes) with gaps between them. Trees, poles and street lamps stand on the sidewalks, pedestrians
// walk there, cars are parked along the curbs. Every object is a closed, outward-oriented surface
// (the ground is an open surface with normals up / towards the road), tessellated so that no
// triangle edge is longer than max_edge_length_m. The same config gives a bit-identical mesh;
// another seed gives another layout.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "shine/geometry/triangle_mesh.hpp"

namespace shine::sim {

/// Parameters of the procedural street. Lengths in metres.
struct StreetSceneConfig {
    std::uint64_t seed = 1;         ///< layout seed: object counts, sizes and positions
    double start_x_m = -70.0;       ///< the street covers x in [start_x_m, start_x_m + length_m]
    double length_m = 190.0;        ///< street length along x
    double road_width_m = 10.0;     ///< two lanes plus parking lanes
    double sidewalk_width_m = 3.0;  ///< on each side of the road
    double curb_height_m = 0.15;    ///< step from road to sidewalk
    double lot_depth_m = 17.0;      ///< ground beyond each sidewalk that holds the buildings
    double building_height_min_m = 5.0;  ///< building heights are drawn in [min, max]
    double building_height_max_m = 20.0;
    double building_setback_max_m = 2.5;  ///< setbacks from the sidewalk are drawn in [0, this]
                                          ///< (at most lot_depth_m - 8.5)
    double building_gap_min_m = 1.5;  ///< gap between neighbouring buildings, drawn in [min, max]
    double building_gap_max_m = 7.0;
    double tree_spacing_m = 11.0;        ///< mean distance between trees along each sidewalk
    double pole_spacing_m = 22.0;        ///< mean distance between poles along each sidewalk
    double car_spacing_m = 9.0;          ///< mean distance between parked cars along each curb
    double pedestrians_per_100m = 10.0;  ///< on both sidewalks together
    double max_edge_length_m = 0.3;      ///< no triangle edge is longer than this
};

/// What a scene part belongs to.
enum class SceneObjectKind { kGround, kBuilding, kTree, kCar, kPole, kPedestrian };

/// Name of a kind ("ground", "building", ...).
std::string to_string(SceneObjectKind kind);

/// What one part of an object is, finer than its kind: what its surface looks like (its colour,
/// sim/scene_albedo.hpp). Recorded while the scene is built; the geometry does not depend on it.
enum class ScenePartSurface : std::uint8_t {
    kGround,           ///< road, curbs, sidewalks and lots: one open surface
    kBuildingBlock,    ///< a building's prism: walls and a flat roof
    kGableRoof,        ///< a gable roof on a building block
    kRoofBox,          ///< a plant room, vent or stair house on a flat roof
    kCarBody,          ///< a parked car's body
    kCarWheel,         ///< one of its wheels
    kTreeTrunk,        ///< a tree's trunk
    kTreeCrown,        ///< a tree's crown
    kPoleMast,         ///< a pole's or street lamp's mast
    kLampArm,          ///< a street lamp's arm over the road
    kLampHead,         ///< a street lamp's head
    kPedestrianLegs,   ///< a pedestrian's legs
    kPedestrianTorso,  ///< a pedestrian's torso and arms
    kPedestrianHead,   ///< a pedestrian's head
};

/// Name of a part surface ("ground", "building block", ...).
std::string to_string(ScenePartSurface surface);

/// A contiguous range of the scene's triangles forming one surface: the ground (open) or one
/// closed part of an object (a building block, a roof box, a trunk, a crown, a wheel, ...).
struct ScenePart {
    SceneObjectKind kind = SceneObjectKind::kGround;
    ScenePartSurface surface = ScenePartSurface::kGround;  ///< what this part of the object is
    std::size_t object_index = 0;  ///< parts of one object (a tree's trunk and crown) share it
    std::size_t first_triangle = 0;
    std::size_t num_triangles = 0;
    bool closed = true;  ///< closed and outward-oriented; false only for the ground
};

/// The street mesh and the parts it consists of (in triangle order).
struct StreetScene {
    TriangleMesh mesh;  ///< face_observed left empty
    std::vector<ScenePart> parts;

    /// Number of objects of `kind` (not parts).
    std::size_t count_objects(SceneObjectKind kind) const;
};

/// Throws ConfigError naming the field if a value is out of range (non-positive sizes, min > max,
/// negative densities, a lot too shallow for buildings).
void validate(const StreetSceneConfig& config);

/// Builds the street. Deterministic for a given config (independent of the thread count).
StreetScene make_street_scene(const StreetSceneConfig& config);

}  // namespace shine::sim
