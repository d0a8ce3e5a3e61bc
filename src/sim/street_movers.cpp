#include "shine/sim/street_movers.hpp"

#include <cmath>
#include <string>

#include "shine/core/error.hpp"
#include "sim_random.hpp"

namespace shine::sim {
namespace street_movers_internal {

using random_internal::Rng;

constexpr double kLaneY_m = 2.3;  ///< lane centres, either side of the road's centre

/// A mover at constant velocity from `start` over [0, end_time_s].
MoverTrack constant_velocity(MoverKind kind, const Eigen::Vector3d& size_m,
                             const Eigen::Vector3d& start_m, double speed_x_mps,
                             double end_time_s) {
    MoverTrack track;
    track.kind = kind;
    track.size_m = size_m;
    const double yaw_rad = speed_x_mps < 0.0 ? M_PI : 0.0;
    track.waypoints.push_back({0.0, start_m, yaw_rad});
    track.waypoints.push_back(
        {end_time_s, start_m + Eigen::Vector3d(speed_x_mps * end_time_s, 0.0, 0.0), yaw_rad});
    return track;
}

}  // namespace street_movers_internal

using namespace street_movers_internal;

Eigen::Vector3d mover_size_m(MoverKind kind) {
    switch (kind) {
        case MoverKind::kCyclist:
            return {1.8, 0.6, 1.7};
        case MoverKind::kPedestrian:
            return {0.5, 0.5, 1.8};
        default:
            return {4.5, 1.8, 1.5};
    }
}

void validate(const StreetMoversConfig& c) {
    if (c.num_movers < 0 || c.num_movers > 1000) {
        throw ConfigError("movers: num_movers = " + std::to_string(c.num_movers) +
                          " must be in [0, 1000]");
    }
    if (!(c.frame_period_s > 0.0 && c.frame_period_s <= 10.0)) {
        throw ConfigError("movers: frame_period_s = " + std::to_string(c.frame_period_s) +
                          " must be in (0, 10]");
    }
    if (!(c.sweep_s >= 0.0 && c.sweep_s <= c.frame_period_s)) {
        throw ConfigError("movers: sweep_s = " + std::to_string(c.sweep_s) +
                          " must be in [0, frame_period_s]");
    }
}

MoverTracks make_street_movers(const StreetMoversConfig& config, const StreetSceneConfig& scene,
                               double drive_length_m, int num_frames, std::uint64_t seed) {
    validate(config);
    MoverTracks tracks;
    tracks.frame_period_s = config.frame_period_s;
    tracks.sweep_s = config.sweep_s;
    tracks.num_frames = num_frames;
    const double end_s = num_frames * config.frame_period_s;  // the last scan's sweep ends here
    const double sensor_speed_mps = drive_length_m / std::max(end_s - config.frame_period_s, 1e-9);
    const double half_road_m = 0.5 * scene.road_width_m;
    const double curb_m = scene.curb_height_m;
    Rng rng(seed);
    // Cars in one lane share its speed and start at least kCarGap_m apart, so that none drives
    // through another.
    constexpr double kCarGap_m = 12.0;
    const double overtaking_mps = sensor_speed_mps + rng.uniform(3.0, 7.0);
    const double oncoming_mps = rng.uniform(8.0, 14.0);
    const double oncoming_start_m =
        drive_length_m * rng.uniform(0.4, 1.0) + oncoming_mps * end_s * rng.uniform(0.2, 0.5);
    int num_overtaking = 0, num_oncoming = 0;
    for (int i = 0; i < config.num_movers; ++i) {
        if (i == 0) {
            // Parked in the right parking lane ahead of the sensor, then pulling out: it
            // accelerates at 2 m/s^2 (a waypoint per second) and keeps 8 m/s.
            MoverTrack car;
            car.kind = MoverKind::kCar;
            car.size_m = mover_size_m(MoverKind::kCar);
            const Eigen::Vector3d parked(drive_length_m * rng.uniform(0.35, 0.65),
                                         -(half_road_m - 1.35), 0.0);
            const double leave_s = end_s * rng.uniform(0.3, 0.5);
            car.waypoints.push_back({0.0, parked, 0.0});
            constexpr double kAccel_mps2 = 2.0;
            double t = leave_s, x = parked.x(), y = parked.y();
            car.waypoints.push_back({t, parked, 0.0});
            for (int k = 1; k <= 4; ++k) {  // pulls into the lane over four seconds
                t = leave_s + k;
                x = parked.x() + 0.5 * kAccel_mps2 * k * k;
                y = parked.y() + (-kLaneY_m - parked.y()) * k / 4.0;
                car.waypoints.push_back({t, Eigen::Vector3d(x, y, 0.0), 0.0});
            }
            const double speed_mps = kAccel_mps2 * 4.0;
            const double stop_s = std::max(end_s, t) + 1.0;
            car.waypoints.push_back(
                {stop_s, Eigen::Vector3d(x + speed_mps * (stop_s - t), y, 0.0), 0.0});
            tracks.movers.push_back(car);
            continue;
        }
        switch ((i - 1) % 4) {
            case 0: {  // overtaking: starts behind the sensor, faster than it
                const Eigen::Vector3d start(
                    -8.0 - kCarGap_m * num_overtaking++ - rng.uniform(0.0, 6.0), -kLaneY_m, 0.0);
                tracks.movers.push_back(constant_velocity(
                    MoverKind::kCar, mover_size_m(MoverKind::kCar), start, overtaking_mps, end_s));
                break;
            }
            case 1: {  // oncoming: starts ahead, meets the sensor during the drive
                const Eigen::Vector3d start(
                    oncoming_start_m + kCarGap_m * num_oncoming++ + rng.uniform(0.0, 6.0), kLaneY_m,
                    0.0);
                tracks.movers.push_back(constant_velocity(
                    MoverKind::kCar, mover_size_m(MoverKind::kCar), start, -oncoming_mps, end_s));
                break;
            }
            case 2:
            case 3: {  // cyclist or pedestrian on a sidewalk, either way
                const bool cyclist = (i - 1) % 4 == 2;
                const double side = rng.chance(0.5) ? 1.0 : -1.0;
                const double direction = rng.chance(0.5) ? 1.0 : -1.0;
                const double speed = cyclist ? rng.uniform(3.0, 6.0) : rng.uniform(0.8, 1.6);
                const Eigen::Vector3d start(rng.uniform(0.0, drive_length_m),
                                            side * (half_road_m + (cyclist ? 1.3 : 2.2)), curb_m);
                tracks.movers.push_back(
                    constant_velocity(cyclist ? MoverKind::kCyclist : MoverKind::kPedestrian,
                                      cyclist ? mover_size_m(MoverKind::kCyclist)
                                              : mover_size_m(MoverKind::kPedestrian),
                                      start, direction * speed, end_s));
                break;
            }
        }
    }
    return tracks;
}

}  // namespace shine::sim
