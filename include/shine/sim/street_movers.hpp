// Moving objects for the simulated street (`shine simulate --movers N`): cars in the lanes (some
// overtaking the sensor's car, some oncoming, the first one parked and then leaving), cyclists
// and pedestrians on the sidewalks, each a box on a piecewise-linear path (io/mover_tracks.hpp).
//
// The street runs along +x with the road centred on y = 0 (street_scene.hpp); the sensor drives
// from x = 0 to drive_length_m at the centre of the road. Lanes: overtaking cars at y = -2.3 m
// heading +x, oncoming cars at y = +2.3 m heading -x, the parked car in the right parking lane;
// cyclists 1.3 m and pedestrians 2.2 m beyond the curbs, on the sidewalk (z = curb height).
// Cars in one lane share one speed and start at least 12 m apart, so none drives through another
// (the leaving car may still meet an overtaking one; cyclists and pedestrians, each at their own
// speed, may pass through each other and through the sidewalk's static objects).
// Movers are made in the order parked car, then overtaking car, oncoming car, cyclist,
// pedestrian, repeated, so N >= 5 has every kind.
#pragma once

#include <cstdint>

#include "shine/io/mover_tracks.hpp"
#include "shine/sim/street_scene.hpp"

namespace shine::sim {

/// How many movers and the clock of the scans.
struct StreetMoversConfig {
    int num_movers = 0;           ///< 0: a static street
    double frame_period_s = 0.1;  ///< scan k starts at k * frame_period_s (10 Hz)
    double sweep_s = 0.1;         ///< one scan's rays spread over this time by azimuth
};

/// The box (length, width, height) of a kind of mover, m: a car 4.5 x 1.8 x 1.5, a cyclist
/// 1.8 x 0.6 x 1.7, a pedestrian 0.5 x 0.5 x 1.8.
Eigen::Vector3d mover_size_m(MoverKind kind);

/// Throws ConfigError naming the field for a negative count (or more than 1000), or a
/// non-positive period or a sweep outside [0, frame_period_s].
void validate(const StreetMoversConfig& config);

/// The movers of a drive of `num_frames` scans from x = 0 to x = drive_length_m along `scene`.
/// Deterministic for a seed.
MoverTracks make_street_movers(const StreetMoversConfig& config, const StreetSceneConfig& scene,
                               double drive_length_m, int num_frames, std::uint64_t seed);

}  // namespace shine::sim
