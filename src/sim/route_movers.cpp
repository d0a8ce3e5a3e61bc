#include "shine/sim/route_movers.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "shine/core/error.hpp"
#include "sim_random.hpp"

namespace shine::sim {
namespace route_movers_internal {

using random_internal::Rng;

constexpr double kStretchLength_m = 100.0;    ///< straights are cut into stretches of about this
constexpr double kMinStretchLength_m = 30.0;  ///< shorter straights get no movers
constexpr double kParkedFromCurb_m = 1.35;    ///< the parking lane's centre
constexpr double kOncomingMinOffset_m = 2.4;  ///< clear of the sensor (1 m range, 0.9 m half car)

/// A straight stretch of the drive: where and when the sensor drives it, and the cross-section
/// of its street in the stretch's frame.
struct Stretch {
    Eigen::Vector2d start_m = Eigen::Vector2d::Zero();  ///< the sensor's lane at the start
    Eigen::Vector2d along = Eigen::Vector2d::UnitX();   ///< unit, the drive's heading
    double length_m = 0.0;
    double begin_s = 0.0;        ///< the sensor enters the stretch
    double end_s = 0.0;          ///< and leaves it
    double speed_mps = 0.0;      ///< the sensor's
    double centre_left_m = 0.0;  ///< the street's centre line, to the left of the lane
    double half_road_m = 0.0;

    Eigen::Vector2d left() const { return {-along.y(), along.x()}; }
    double yaw_rad() const { return std::atan2(along.y(), along.x()); }
    /// World position of (x along, y to the left) at height z.
    Eigen::Vector3d at(double x_m, double y_m, double z_m) const {
        const Eigen::Vector2d p = start_m + x_m * along + y_m * left();
        return {p.x(), p.y(), z_m};
    }
};

/// The street line a straight piece runs on: the rows for a piece along x, the rungs along y; the
/// one whose road holds the piece's start.
const StreetLine* line_of(const CityRoute& route, const PathPiece& piece) {
    const bool along_x = std::abs(piece.direction.x()) > std::abs(piece.direction.y());
    const std::vector<StreetLine>& lines = along_x ? route.rows : route.rungs;
    const double across_m = along_x ? piece.start_m.y() : piece.start_m.x();
    for (const StreetLine& line : lines) {
        if (std::abs(across_m - line.center_m) < line.half_road_m) return &line;
    }
    return nullptr;
}

/// The track cut at `end_s`: waypoints after it dropped, the pose at end_s added.
void end_at(MoverTrack& track, double end_s) {
    const Eigen::Isometry3d T = track.T_world_body(end_s);
    const double yaw_rad = std::atan2(T.linear()(1, 0), T.linear()(0, 0));
    while (!track.waypoints.empty() && track.waypoints.back().time_s >= end_s) {
        track.waypoints.pop_back();
    }
    track.waypoints.push_back({end_s, T.translation(), yaw_rad});
}

/// A body at constant velocity along the stretch over its whole time.
MoverTrack along_stretch(const Stretch& st, MoverKind kind, double x_at_begin_m, double y_m,
                         double z_m, double speed_mps) {
    MoverTrack track;
    track.kind = kind;
    track.size_m = mover_size_m(kind);
    const double yaw_rad = st.yaw_rad() + (speed_mps < 0.0 ? M_PI : 0.0);
    const double duration_s = st.end_s - st.begin_s;
    track.waypoints.push_back({st.begin_s, st.at(x_at_begin_m, y_m, z_m), yaw_rad});
    track.waypoints.push_back(
        {st.end_s, st.at(x_at_begin_m + speed_mps * duration_s, y_m, z_m), yaw_rad});
    return track;
}

/// The part of `track` while its body's centre lies along the stretch (x in [from_m, to_m]):
/// a body that drives in from beyond the stretch's junction appears there. Returns an empty
/// track if it never does.
MoverTrack within_stretch(const Stretch& st, MoverTrack track, double from_m, double to_m) {
    const MoverWaypoint a = track.waypoints.front();
    const MoverWaypoint b = track.waypoints.back();
    const double x0_m = (a.position_m.head<2>() - st.start_m).dot(st.along);
    const double x1_m = (b.position_m.head<2>() - st.start_m).dot(st.along);
    double t0_s = a.time_s, t1_s = b.time_s;
    if (x1_m != x0_m) {
        const double ta_s = a.time_s + (from_m - x0_m) / (x1_m - x0_m) * (b.time_s - a.time_s);
        const double tb_s = a.time_s + (to_m - x0_m) / (x1_m - x0_m) * (b.time_s - a.time_s);
        t0_s = std::max(t0_s, std::min(ta_s, tb_s));
        t1_s = std::min(t1_s, std::max(ta_s, tb_s));
    } else if (x0_m < from_m || x0_m > to_m) {
        t1_s = t0_s - 1.0;
    }
    if (!(t1_s - t0_s > 1e-3)) return {};
    MoverTrack cut = track;
    cut.waypoints = {{t0_s, track.T_world_body(t0_s).translation(), a.yaw_rad},
                     {t1_s, track.T_world_body(t1_s).translation(), a.yaw_rad}};
    return cut;
}

/// Whether a car's footprint at (x, y) of the stretch, grown by `margin_m`, overlaps a static
/// object's footprint.
bool blocked(const Stretch& st, double x_m, double y_m, double margin_m,
             const std::vector<Eigen::AlignedBox2d>& obstacles_m) {
    const Eigen::Vector3d c = st.at(x_m, y_m, 0.0);
    const Eigen::Vector3d car_m = mover_size_m(MoverKind::kCar);
    const Eigen::Vector2d half_along = (0.5 * car_m.x() + margin_m) * st.along.cwiseAbs();
    const Eigen::Vector2d half_across = (0.5 * car_m.y() + margin_m) * st.left().cwiseAbs();
    const Eigen::Vector2d half = half_along + half_across;
    const Eigen::AlignedBox2d box(c.head<2>() - half, c.head<2>() + half);
    for (const Eigen::AlignedBox2d& o : obstacles_m) {
        if (o.intersects(box)) return true;
    }
    return false;
}

/// A car parked in a gap of the right parking lane that pulls out into the sensor's lane once the
/// sensor has passed it; an empty track where the stretch has no gap.
MoverTrack parked_car_that_leaves(const Stretch& st,
                                  const std::vector<Eigen::AlignedBox2d>& obstacles_m, Rng& rng) {
    constexpr double kAccel_mps2 = 2.0;
    const double parked_y_m = st.centre_left_m - st.half_road_m + kParkedFromCurb_m;
    // Where the car is k seconds after it starts to pull out (into the sensor's lane over three
    // seconds).
    auto pull_out = [&](double x_m, double k) {
        return Eigen::Vector2d(x_m + 0.5 * kAccel_mps2 * k * k,
                               parked_y_m * std::max(0.0, 1.0 - k / 3.0));
    };
    double parked_x_m = -1.0;
    for (int attempt = 0; attempt < 40 && parked_x_m < 0.0; ++attempt) {
        const double x_m = st.length_m * rng.uniform(0.3, 0.7);
        // Room to stand, and for its first second out (later it may graze the next parked car's
        // corner).
        bool clear = !blocked(st, x_m, parked_y_m, 0.3, obstacles_m);
        for (const double k : {0.5, 1.0}) {
            const Eigen::Vector2d p = pull_out(x_m, k);
            clear = clear && !blocked(st, p.x(), p.y(), 0.1, obstacles_m);
        }
        if (clear) parked_x_m = x_m;
    }
    if (parked_x_m < 0.0) return {};
    MoverTrack car;
    car.kind = MoverKind::kCar;
    car.size_m = mover_size_m(MoverKind::kCar);
    const Eigen::Vector3d parked = st.at(parked_x_m, parked_y_m, 0.0);
    const double leave_s = st.begin_s + parked_x_m / st.speed_mps + rng.uniform(0.0, 1.0);
    car.waypoints.push_back({st.begin_s, parked, st.yaw_rad()});
    if (leave_s < st.end_s) {
        car.waypoints.push_back({leave_s, parked, st.yaw_rad()});
        double x_m = parked_x_m;
        for (int k = 1; k <= 4; ++k) {  // 8 m/s after four seconds
            const Eigen::Vector2d p = pull_out(parked_x_m, k);
            x_m = p.x();
            car.waypoints.push_back({leave_s + k, st.at(p.x(), p.y(), 0.0), st.yaw_rad()});
        }
        const double after_s = std::max(st.end_s, leave_s + 4.0) + 1.0;
        car.waypoints.push_back(
            {after_s, st.at(x_m + 4.0 * kAccel_mps2 * (after_s - leave_s - 4.0), 0.0, 0.0),
             st.yaw_rad()});
    } else {
        car.waypoints.push_back({st.end_s + 1.0, parked, st.yaw_rad()});
    }
    end_at(car, st.end_s);
    return car;
}

/// A car ahead in the sensor's lane, on the drive's own path (so it turns where the drive turns),
/// `path_m` being the stretch's start along it: a waypoint every metre of its way.
MoverTrack car_ahead(const Stretch& st, const LoopPath& path, double path_m, Rng& rng) {
    MoverTrack car;
    car.kind = MoverKind::kCar;
    car.size_m = mover_size_m(MoverKind::kCar);
    const double gap_m = rng.uniform(15.0, 30.0);
    const double speed_mps = st.speed_mps + rng.uniform(-1.0, 2.0);
    const double duration_s = st.end_s - st.begin_s;
    const int steps = std::max(1, static_cast<int>(std::ceil(speed_mps * duration_s)));
    for (int k = 0; k <= steps; ++k) {
        const double t_s = st.begin_s + duration_s * k / steps;
        Eigen::Vector2d position_m, heading;
        path.sample(path_m + gap_m + speed_mps * (t_s - st.begin_s), position_m, heading);
        car.waypoints.push_back({t_s, Eigen::Vector3d(position_m.x(), position_m.y(), 0.0),
                                 std::atan2(heading.y(), heading.x())});
    }
    // Unwrapped headings, so that interpolation turns the short way.
    for (std::size_t k = 1; k < car.waypoints.size(); ++k) {
        double& yaw = car.waypoints[k].yaw_rad;
        const double previous = car.waypoints[k - 1].yaw_rad;
        while (yaw - previous > M_PI) yaw -= 2.0 * M_PI;
        while (yaw - previous < -M_PI) yaw += 2.0 * M_PI;
    }
    return car;
}

/// A car in the opposite lane that meets the sensor along the stretch; it appears at the
/// stretch's far end (out of the junction) and leaves at its near end.
MoverTrack oncoming_car(const Stretch& st, Rng& rng) {
    const double offset_m = std::max(2.0 * st.centre_left_m, kOncomingMinOffset_m);
    const double speed_mps = rng.uniform(8.0, 14.0);
    const double meet_x_m = st.length_m * rng.uniform(0.3, 0.9);
    const double meet_s = st.begin_s + meet_x_m / st.speed_mps;
    return within_stretch(
        st,
        along_stretch(st, MoverKind::kCar, meet_x_m + speed_mps * (meet_s - st.begin_s), offset_m,
                      0.0, -speed_mps),
        0.0, st.length_m);
}

/// A cyclist or a pedestrian on either sidewalk, going either way, while it is along the stretch.
MoverTrack sidewalk_mover(const Stretch& st, MoverKind kind, double curb_height_m, Rng& rng) {
    const bool cyclist = kind == MoverKind::kCyclist;
    const double beyond_m = cyclist ? 1.3 : 2.2;
    const double y_m = rng.chance(0.5) ? st.centre_left_m - st.half_road_m - beyond_m
                                       : st.centre_left_m + st.half_road_m + beyond_m;
    const double direction = rng.chance(0.5) ? 1.0 : -1.0;
    const double speed_mps = cyclist ? rng.uniform(3.0, 6.0) : rng.uniform(0.8, 1.6);
    return within_stretch(st,
                          along_stretch(st, kind, rng.uniform(0.0, st.length_m), y_m, curb_height_m,
                                        direction * speed_mps),
                          0.0, st.length_m);
}

/// Mover number `kind_index` of a stretch, in the street's order: the parked car that leaves,
/// the car ahead, the oncoming car, the cyclist, the pedestrian.
MoverTrack make_mover(const Stretch& st, const LoopPath& path, double path_m, int kind_index,
                      double curb_height_m, const std::vector<Eigen::AlignedBox2d>& obstacles_m,
                      Rng& rng) {
    switch (kind_index) {
        case 0:
            return parked_car_that_leaves(st, obstacles_m, rng);
        case 1:
            return car_ahead(st, path, path_m, rng);
        case 2:
            return oncoming_car(st, rng);
        case 3:
            return sidewalk_mover(st, MoverKind::kCyclist, curb_height_m, rng);
        default:
            return sidewalk_mover(st, MoverKind::kPedestrian, curb_height_m, rng);
    }
}

}  // namespace route_movers_internal

using namespace route_movers_internal;

std::vector<Eigen::AlignedBox2d> obstacle_footprints(const StreetScene& scene, double below_m) {
    std::vector<Eigen::AlignedBox2d> boxes;
    for (const ScenePart& part : scene.parts) {
        if (part.kind == SceneObjectKind::kGround) continue;
        Eigen::AlignedBox3d box;
        for (std::size_t t = part.first_triangle; t < part.first_triangle + part.num_triangles;
             ++t) {
            for (int corner = 0; corner < 3; ++corner) {
                box.extend(scene.mesh.vertices[scene.mesh.triangles[t][corner]].cast<double>());
            }
        }
        if (!box.isEmpty() && box.min().z() < below_m) {
            boxes.emplace_back(box.min().head<2>(), box.max().head<2>());
        }
    }
    return boxes;
}

MoverTracks make_route_movers(const StreetMoversConfig& config, const CityRoute& route,
                              const DriveTrajectoryConfig& trajectory, int num_frames,
                              const std::vector<Eigen::AlignedBox2d>& obstacles_m,
                              std::uint64_t seed) {
    validate(config);
    MoverTracks tracks;
    tracks.frame_period_s = config.frame_period_s;
    tracks.sweep_s = config.sweep_s;
    tracks.num_frames = num_frames;
    if (config.num_movers == 0 || num_frames < 2) return tracks;
    const double speed_mps = trajectory.frame_spacing_m / config.frame_period_s;
    const double drive_end_m = (num_frames - 1) * trajectory.frame_spacing_m;
    Rng rng(seed);
    int kind_counter = 0;
    // The drive: the loop, then its first pieces again (the revisit).
    double piece_start_m = 0.0;
    while (piece_start_m < drive_end_m) {
        for (const PathPiece& piece : route.loop.pieces()) {
            const double begin_m = piece_start_m;
            piece_start_m += piece.length_m;
            if (begin_m >= drive_end_m) break;
            if (piece.turn != 0) continue;
            const StreetLine* line = line_of(route, piece);
            if (!line) {
                throw ConfigError("route movers: a straight of the drive at (" +
                                  std::to_string(piece.start_m.x()) + ", " +
                                  std::to_string(piece.start_m.y()) + ") lies on no street");
            }
            const double driven_m = std::min(piece.length_m, drive_end_m - begin_m);
            if (driven_m < kMinStretchLength_m) continue;
            const int num_stretches =
                std::max(1, static_cast<int>(std::lround(driven_m / kStretchLength_m)));
            const Eigen::Vector2d left(-piece.direction.y(), piece.direction.x());
            const Eigen::Vector2d centre_point =
                std::abs(piece.direction.x()) > std::abs(piece.direction.y())
                    ? Eigen::Vector2d(piece.start_m.x(), line->center_m)
                    : Eigen::Vector2d(line->center_m, piece.start_m.y());
            for (int k = 0; k < num_stretches; ++k) {
                Stretch st;
                st.length_m = driven_m / num_stretches;
                st.along = piece.direction;
                st.start_m = piece.start_m + k * st.length_m * piece.direction;
                st.begin_s = (begin_m + k * st.length_m) / speed_mps;
                st.end_s = st.begin_s + st.length_m / speed_mps;
                st.speed_mps = speed_mps;
                st.centre_left_m = (centre_point - piece.start_m).dot(left);
                st.half_road_m = line->half_road_m;
                const int count = std::max(
                    1, static_cast<int>(std::lround(config.num_movers * st.length_m / 100.0)));
                const double stretch_path_m = begin_m + k * st.length_m;
                for (int i = 0; i < count; ++i) {
                    MoverTrack mover =
                        make_mover(st, route.loop, stretch_path_m, kind_counter++ % 5,
                                   route.street.curb_height_m, obstacles_m, rng);
                    if (!mover.waypoints.empty()) tracks.movers.push_back(std::move(mover));
                }
            }
        }
    }
    return tracks;
}

}  // namespace shine::sim
