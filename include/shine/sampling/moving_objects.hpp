// Moving objects: compact objects that the scans around them hold further on, at a steady
// velocity.
//
// The free-space votes (free_space_votes.hpp) need a later or earlier ray through the place a
// mover was. Some movers never give one: the cars of a lane behind the sensor, each hiding the
// place of the one before, and far cars, whose few returns the scans around them hit again within
// the votes' margin as the car closes in. What they do give is motion: between scans 0.1 s apart
// a car moves a metre or more, as a rigid body and at a nearly steady velocity, which no static
// object does. Per scan (map frame, z up), over the compact objects of find_scan_objects (with
// min_points and taller voxels, voxel_height_m, so that the few rows a far car gets stay one
// object):
//   1. velocity: an object's best horizontal steps towards the next scan and from the one
//      before (a grid of search_m up to max_step_m; a point matches when the other scan has an
//      object point in its cell of match_m or one of the 26 around) are its candidate
//      velocities; each is refined on the scans around it. The object moves when, moved at the
//      velocity, it matches (min_match_share of its points) at least min_scan_share of the
//      window_scans scans on either side, and left in place at most max_still_share of them: a
//      static object matches where it is, a chance match at some step does not hold over ten
//      scans, and a car's sides, which slide along themselves, match both ways and stay;
//   2. reach: from each moving object, both ways in time at its velocity, an object of a scan up
//      to max_gap_scans away that lies where it is predicted (link_share of its points land on
//      it when moved back) and that the scans beside it do not hold in place moves too: the
//      parts of a car too small or too changeable to show a velocity of their own.
// The points of moving objects are dynamic (free_space_votes.hpp's filter drops them).
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "shine/sampling/dynamic_objects.hpp"

namespace shine {

/// Settings of the motion test (YAML `dynamic.motion` and `dynamic.motion_*`). Lengths in metres
/// and steps in metres a scan: the motion of cars and cyclists between the scans of a 10 Hz
/// sensor; pedestrians (0.1-0.2 m a scan) are below min_step_m. Measured on the street with 20
/// movers, the streets without and the real walk (docs/movers.md).
struct MovingObjectConfig {
    bool enabled = true;  ///< false: no point is dynamic by its motion
    /// Incremental mode: also test each new scan against the scans before it while it maps
    /// (PastMotion). Off by default: on the 4 km city, which has no movers, it found 13,540
    /// objects moving, and the odometry's ATE grew from 4.0 to 6.1 cm (docs/movers.md).
    bool while_mapping = false;
    /// Height of the segmentation's voxels (DynamicObjectConfig::voxel_height_m): a 64-beam
    /// sensor's rows lie 0.42 m apart at 57 m.
    float voxel_height_m = 0.5f;
    int min_points = 3;            ///< smaller objects are not tested
    float match_m = 0.2f;          ///< cell of the point match (a match is within 1-2 cells)
    float max_step_m = 2.5f;       ///< fastest step searched (25 m/s at 10 Hz)
    float search_m = 0.25f;        ///< grid of the steps searched
    float min_step_m = 0.5f;       ///< slower objects do not move (5 m/s at 10 Hz)
    float min_match_share = 0.6f;  ///< of an object's points, for it to match a scan
    /// The candidates: steps where the object matches on at most 1 - min_gain of its points
    /// unshifted.
    float min_gain = 0.3f;
    int window_scans = 5;          ///< scans on either side that test a velocity
    int min_window_scans = 3;      ///< fewer scans in the window (a sequence's start) test none
    float min_scan_share = 0.6f;   ///< of them, matched by the object moved at its velocity
    float max_still_share = 0.3f;  ///< and at most this many by the object left in place
    float link_share = 0.6f;       ///< of an object's points that land on the moving object (reach)
    int max_gap_scans = 2;         ///< reach looks this many scans on when the next one has nothing
};

/// What the motion test found.
struct MovingObjectStats {
    std::size_t objects = 0;         ///< objects of at least min_points points, all scans
    std::size_t moved = 0;           ///< of them, moving by their own velocity (step 1)
    std::size_t moving_objects = 0;  ///< moving ones, the reached included
    std::size_t points = 0;          ///< their points
};

/// moving[s][i] = 1 for point i of scan s (scans in time order, map frame with z up) when it lies
/// on a moving object. The objects are those of find_scan_objects with `objects` and
/// config.min_points and voxel_height_m. Long sequences go in chunks of 64 scans, each with the
/// 2 * window_scans + max_gap_scans scans around it (so the cells of at most about 90 scans are
/// held at once). Deterministic; parallel over the scans. Throws
/// ConfigError for settings out of range and DataError for a null scan.
std::vector<std::vector<std::uint8_t>> find_moving_points(
    const std::vector<const std::vector<Eigen::Vector3f>*>& scans_map,
    const DynamicObjectConfig& objects, const MovingObjectConfig& config,
    MovingObjectStats* stats = nullptr);

/// The motion test while the scans arrive (incremental mode): each new scan's objects against
/// the window_scans scans before it only (step 1 on one side; no reach), so that a mover's points
/// leave before they train. Holds the last window_scans scans' points and cells.
class PastMotion {
  public:
    /// Throws ConfigError for settings out of range.
    PastMotion(const DynamicObjectConfig& objects, const MovingObjectConfig& config);
    ~PastMotion();
    PastMotion(PastMotion&&) noexcept;
    PastMotion& operator=(PastMotion&&) noexcept;

    /// Flags (1) the points of `points_map`, the newest scan in the map frame, that lie on an
    /// object moving by the scans before it (at least min_window_scans of them), and keeps the
    /// scan for the scans after it.
    std::vector<std::uint8_t> add_scan(const std::vector<Eigen::Vector3f>& points_map,
                                       MovingObjectStats* stats = nullptr);
    /// Forgets the scans kept.
    void clear();

  private:
    struct State;
    std::unique_ptr<State> state_;
};

}  // namespace shine
