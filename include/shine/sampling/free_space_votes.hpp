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
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

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
    float min_free_share = 0.3f;  ///< of the free + hit votes
};

/// The votes a point received.
struct FreeSpaceVotes {
    std::uint16_t free = 0;
    std::uint16_t hit = 0;
};

/// Adds the votes of one scan (its range image and the map-to-sensor transform of its pose) to
/// the `count` points at `points_map` (votes[i] for points_map[i]). Parallel over the points.
void add_free_space_votes(const RangeImage& image, const Eigen::Isometry3f& T_sensor_map,
                          const Eigen::Vector3f* points_map, std::size_t count,
                          const DynamicPointConfig& config, FreeSpaceVotes* votes);

/// Whether votes make a point dynamic (min_free_votes, min_free_share).
bool is_dynamic(const FreeSpaceVotes& votes, const DynamicPointConfig& config);

/// Throws ConfigError naming the `dynamic.*` key of an out-of-range value.
void check_dynamic_point_config(const DynamicPointConfig& config);

}  // namespace shine
