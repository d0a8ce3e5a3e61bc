// A deterministic object-scale scene: a shoebox-sized object standing on a turntable plate, the
// reference geometry of `shine simulate --scene object`.
//
// World z is up; the plate's top is z = 0 and its centre the origin. The object is a box (the
// "shoebox") under a slightly larger lid, with a cylinder, an ellipsoid and a small wedge-like box
// standing on the lid and a second cylinder beside the box: flat faces, sharp edges, curved
// surfaces and concave corners between parts, from a few millimetres to the box's ~0.3 m. Every
// part is a closed, outward-oriented surface tessellated so that no triangle edge is longer than
// max_edge_length_m (small against the scanner's ~1.5 mm ray spacing at 1 m, so that "a ray hit
// this triangle" marks observed surface precisely). The seed moves and turns the small parts a
// little; the same config gives a bit-identical mesh.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>

#include "shine/geometry/triangle_mesh.hpp"

namespace shine::sim {

/// Parameters of the object scene. Lengths in metres.
struct ObjectSceneConfig {
    std::uint64_t seed = 1;            ///< placement of the small parts
    double plate_size_m = 0.5;         ///< the square plate's edge
    double plate_thickness_m = 0.01;   ///< from z = -thickness to z = 0
    double box_length_m = 0.28;        ///< the shoebox along x
    double box_width_m = 0.16;         ///< along y
    double box_height_m = 0.1;         ///< along z, lid included
    double max_edge_length_m = 0.002;  ///< no triangle edge is longer than this
};

/// The object scene's mesh and the object's extent (plate excluded).
struct ObjectScene {
    TriangleMesh mesh;             ///< face_observed left empty
    Eigen::AlignedBox3d object_m;  ///< bounding box of the object's parts (not the plate)
    std::size_t num_parts = 0;     ///< closed parts, plate included
};

/// Throws ConfigError naming the field if a value is out of range (non-positive sizes, an object
/// larger than the plate, an edge length outside [0.2 mm, 5 cm]).
void validate(const ObjectSceneConfig& config);

/// Builds the object scene. Deterministic for a given config.
ObjectScene make_object_scene(const ObjectSceneConfig& config);

}  // namespace shine::sim
