// Dynamic points: scan points whose place other scans see through.
//
// A static surface seen by scan k at point p is, for another scan j that looks towards p, either
// hit near p or hidden behind something nearer; no scan measures a return *beyond* p along the
// same direction. A car that drove on, a pedestrian who walked by, a parked car that left: other
// scans look through the place where they were and measure the street behind. So each other scan
// j votes on p from its range image (range_image.hpp), looking along the direction from its
// sensor to p at distance d:
//   - free   if the nearest return within +-window_bins bins is beyond d + margin,
//   - hit    if it is within d +- margin,
//   - nothing if it is nearer (p is hidden from j) or j has no return there (sky, no beam).
// The nearest return of a window, not the centre bin's, makes a free vote conservative: at a
// depth edge or on ground seen at a grazing angle some ray of the window falls on the surface
// itself or in front of it. margin = margin_m (the data's accuracy: twice the surface band, which
// follows the scene, MapperConfig::finalize) + beam_margin bin widths at distance d (the beam's
// footprint grows with range), so nothing in it is street-specific.
// A point is dynamic when at least min_free_votes scans saw through it and they are at least
// min_free_share of the scans that voted (free or hit): a parked car seen by the scans of the
// first half of a drive and seen through by the second half is dynamic; a surface that one noisy
// scan missed is not.
// Batch mode also asks scans farther away (far_vote_frames): an oncoming car seen far ahead, a
// cyclist or a pedestrian is seen through only by scans more than vote_frames away, when the
// sensor has come near. Their votes count apart and only for a point that the near scans hit at
// most far_max_near_hits times: a static surface seen at a grazing angle from far viewpoints gets
// false free votes there, but the near scans hit it (docs/movers.md).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "shine/sampling/dynamic_objects.hpp"
#include "shine/sampling/moving_objects.hpp"
#include "shine/sampling/range_image.hpp"

namespace shine {

/// The dynamic-point filter of both mappers (YAML section `dynamic`).
struct DynamicPointConfig {
    bool enabled = true;  ///< false: every point is mapped, as before the filter existed
    /// Scans that vote on a scan's points: this many before and after it in batch mode, this
    /// many before it in incremental mode (only the past is known there).
    int vote_frames = 10;
    int window_bins = 1;  ///< radius of the window of bins searched around a direction
    /// Range tolerance of a hit (m); follows twice sampling.surface_band_m (0.2 m outdoors).
    float margin_m = 0.2f;
    float beam_margin = 2.0f;  ///< plus this many bin widths at the point's distance
    int min_free_votes = 2;
    /// Of the free + hit votes. 40 %: on the real walk 28 % of the points 30 % would drop are
    /// static (ground and walls at 3-10 m that the near scans hit too) with 30-40 % free votes,
    /// against 0.7 % of the dropped points on the street's movers (docs/movers.md).
    float min_free_share = 0.4f;
    /// Batch mode: the scans from vote_frames + 1 to this many before and after a scan vote
    /// apart (far votes); 0 (or at most vote_frames) asks no far scans. Incremental mode, which
    /// knows only the past while it maps, asks them before its consolidation: the kept scans vote
    /// on each other from both sides, near and far, and the compact objects those votes make
    /// dynamic leave it (IncrementalMapper::vote_among_kept_scans).
    /// 50 (25 before): the 20-mover street's ghosts 1.95 -> 1.63 %, the real walk's held-out rays
    /// within 10 cm +0.08 / +0.06 points, the static streets -0.10 to -0.15 points
    /// (docs/movers.md).
    int far_vote_frames = 50;
    /// A point is dynamic by its far votes only if the near scans hit it at most this often.
    int far_max_near_hits = 1;
    /// Of the far free + far hit votes (at least min_free_votes far free votes too).
    float far_min_free_share = 0.5f;
    /// Compact objects most of whose points are dynamic are dropped whole (dynamic_objects.hpp).
    DynamicObjectConfig objects;
    /// Compact objects that move at a steady velocity over the scans around them, and the objects
    /// where they are predicted, are dynamic whole (moving_objects.hpp).
    MovingObjectConfig motion;
};

/// The votes a point received: from the near scans (vote_frames) and the far ones.
struct FreeSpaceVotes {
    std::uint16_t free = 0;
    std::uint16_t hit = 0;
    std::uint16_t far_free = 0;
    std::uint16_t far_hit = 0;
};

/// Adds the votes of one scan (its range image and the map-to-sensor transform of its pose) to
/// the `count` points at `points_map` (votes[i] for points_map[i]), as far votes if `far`.
/// Parallel over the points.
void add_free_space_votes(const RangeImage& image, const Eigen::Isometry3f& T_sensor_map,
                          const Eigen::Vector3f* points_map, std::size_t count,
                          const DynamicPointConfig& config, FreeSpaceVotes* votes,
                          bool far = false);

/// Whether votes make a point dynamic: by its near votes (min_free_votes, min_free_share), or by
/// its far votes if the near scans hit it at most far_max_near_hits times (far_min_free_share).
bool is_dynamic(const FreeSpaceVotes& votes, const DynamicPointConfig& config);

/// Throws ConfigError naming the `dynamic.*` key of an out-of-range value.
void check_dynamic_point_config(const DynamicPointConfig& config);

}  // namespace shine
