// Moving objects for the city drive (`shine simulate --route-km K --movers N`): on every straight
// stretch of the drive, the traffic a car meets while it passes -- each a box on a
// piecewise-linear path (io/mover_tracks.hpp) that is present only while the sensor drives that
// stretch, so a mover never stands in a street the drive comes back to later.
//
// A straight of the drive's path (city_route.hpp: the loop's straight pieces, and the revisit's)
// is cut into stretches of about 100 m, each with N * length / 100 m movers (at least one). In a
// stretch's frame (x along the drive from the stretch's start, y to the left of the sensor's lane)
// and with the street line's cross-section (its centre c to the left, the curbs at c -/+ the half
// road), the kinds come in the street's order (street_movers.hpp), counted over the whole drive:
//   - a parked car in a gap of the right parking lane (1.35 m from the curb) that pulls out into
//     the lane behind the sensor once it has passed (over 3 s), accelerating at 2 m/s^2 up to
//     8 m/s; a stretch with no gap for it has none;
//   - a car ahead in the sensor's own lane (15-30 m ahead, within -1..+2 m/s of its speed) on the
//     drive's own path, turning where it turns: the traffic a city drive follows, which keeps
//     its distance;
//   - an oncoming car in the opposite lane (mirrored about the centre, at least 2.4 m to the
//     left), 8-14 m/s, meeting the sensor 30-90 % along the stretch; it appears at the
//     stretch's far end and leaves at its near end;
//   - a cyclist (3-6 m/s) 1.3 m and a pedestrian (0.8-1.6 m/s) 2.2 m beyond either curb, on the
//     sidewalk, going either way, while they are along the stretch.
// The sensor drives at frame_spacing_m / frame_period_s (16 m/s by default), so the parked car
// that leaves stays behind it. Nothing keeps a mover out of the street's static objects (a
// pedestrian may walk through a pole, the leaving car may touch a parked one).
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <vector>

#include "shine/io/mover_tracks.hpp"
#include "shine/sim/city_route.hpp"
#include "shine/sim/drive_trajectory.hpp"
#include "shine/sim/street_movers.hpp"
#include "shine/sim/street_scene.hpp"

namespace shine::sim {

/// The horizontal footprints (world x-y) of `scene`'s object parts that reach below `below_m`,
/// one box per part and none for the ground: what blocks a car's way (a tree's crown or a lamp's
/// arm over the road does not).
std::vector<Eigen::AlignedBox2d> obstacle_footprints(const StreetScene& scene,
                                                     double below_m = 2.0);

/// The movers of the drive along `route` (num_frames scans, one every trajectory.frame_spacing_m
/// of arc length, scan k at k * config.frame_period_s); config.num_movers is the number per 100 m
/// of straight drive. `obstacles_m` are the static objects' footprints (world x-y): the parked
/// car is placed in a gap between them, or left out where the stretch has none. Deterministic
/// for a seed. Throws ConfigError as validate(config) does.
MoverTracks make_route_movers(const StreetMoversConfig& config, const CityRoute& route,
                              const DriveTrajectoryConfig& trajectory, int num_frames,
                              const std::vector<Eigen::AlignedBox2d>& obstacles_m,
                              std::uint64_t seed);

}  // namespace shine::sim
