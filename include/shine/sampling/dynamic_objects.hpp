// Dynamic objects: a compact object of one scan most of whose points other scans see through is
// dropped whole.
//
// The free-space votes (free_space_votes.hpp) judge each point alone, and a mover is seen through
// only where a later (or earlier) scan's rays pass its place: a car in a lane where the next car
// always hides it, or the side of a car that no other scan looked behind, keeps most of its points
// although some of them were seen through. A point belongs to a rigid object with its neighbours,
// so the votes of part of an object speak for all of it. Per scan (map frame, z up):
//   1. ground: each point's height above the lowest point of the scan within the 3 x 3 cells of
//      ground_cell_m around it; points less than min_height_m above it are ground and are left
//      to their own votes (the road under a car is static);
//   2. objects: the other points, joined when their voxels of voxel_m touch (26-neighbourhood);
//   3. an object no wider (horizontal bounding-box diagonal) than max_extent_m, no taller than
//      max_height_m, with at least min_points points of which at least min_dynamic_share are
//      dynamic, becomes dynamic whole. Buildings, hedges and rows of parked cars are wider than a
//      car, so a few false free votes on them (grazing angles) never spread.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace shine {

/// Settings of the propagation (YAML `dynamic.object_*`). The lengths are those of the things
/// that move in streets and rooms (cars, cyclists, people), in metres whatever the map's leaf;
/// on the object scene, where nothing of that size moves, the propagation is off by default
/// (MapperConfig). Measured on the street with 20 movers, three streets without and the real walk
/// (docs/movers.md).
struct DynamicObjectConfig {
    /// Share of an object's points that must be dynamic for all of them to be; 0 switches the
    /// propagation off.
    float min_dynamic_share = 0.15f;
    int min_points = 5;          ///< smaller objects keep their points' own votes
    int min_dynamic_points = 3;  ///< and so do objects with fewer dynamic points
    float voxel_m = 0.3f;        ///< points in touching voxels of this size are one object
    /// Height of the voxels; 0: voxel_m. Taller voxels join the returns of a far object, which
    /// the beams sample further apart vertically than horizontally.
    float voxel_height_m = 0.0f;
    float ground_cell_m = 2.0f;  ///< cells of the local ground height
    float min_height_m = 0.2f;   ///< points lower above the local ground are ground
    float max_extent_m = 8.0f;   ///< wider objects (horizontal diagonal) are structures
    float max_height_m = 4.0f;   ///< taller objects are structures
};

/// What the propagation did to one scan.
struct DynamicObjectStats {
    std::size_t objects = 0;          ///< compact objects (ScanObjects::num_objects)
    std::size_t objects_dynamic = 0;  ///< of them, made dynamic whole
    std::size_t points_added = 0;     ///< points made dynamic that were not before
};

/// The compact objects of one scan (steps 1 and 2, and step 3's size rules): object_of[i] is
/// point i's object, in [0, num_objects), or kNoObject for ground points and the points of
/// objects too small (min_points), too wide or too tall to be a mover.
struct ScanObjects {
    static constexpr std::uint32_t kNoObject = 0xffffffffu;
    std::vector<std::uint32_t> object_of;
    std::uint32_t num_objects = 0;
};

/// Finds the compact objects of `points_map` (one scan, map frame with z up); see the file
/// comment. Deterministic. Throws ConfigError for non-positive sizes.
ScanObjects find_scan_objects(const std::vector<Eigen::Vector3f>& points_map,
                              const DynamicObjectConfig& config);

/// Step 3's vote: marks dynamic (dynamic[i] = 1) every point of each object whose share of
/// dynamic points reaches config.min_dynamic_share (and min_dynamic_points). `objects` may be an
/// earlier segmentation of the same scan with points removed since, in order (incremental mode
/// keeps each scan's objects while later scans vote on it): the shares count the points left.
/// Returns at once (all counts 0) when no point is dynamic or the share is 0. Throws DataError if
/// the sizes differ.
DynamicObjectStats spread_dynamic_to_objects(const ScanObjects& objects,
                                             std::vector<std::uint8_t>& dynamic,
                                             const DynamicObjectConfig& config);

/// find_scan_objects, then spread_dynamic_to_objects (no segmentation when nothing is dynamic).
DynamicObjectStats spread_dynamic_to_objects(const std::vector<Eigen::Vector3f>& points_map,
                                             std::vector<std::uint8_t>& dynamic,
                                             const DynamicObjectConfig& config);

}  // namespace shine
