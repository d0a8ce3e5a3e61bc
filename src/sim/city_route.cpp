#include "shine/sim/city_route.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "shine/core/error.hpp"
#include "sim_random.hpp"

namespace shine::sim {
namespace city_internal {

using random_internal::derive_seed;
using random_internal::Rng;

constexpr double kGrid_m = 0.125;              ///< lines and spacings are multiples: float-exact
constexpr double kMinStreetLength_m = 20.0;    ///< make_street_scene's shortest street
constexpr double kLotGap_m = 1.0;              ///< between the lots of neighbouring rungs
constexpr double kMaxRouteLength_m = 20000.0;  ///< ~5x KITTI 00; the scene needs ~0.55 GB/km
constexpr int kMaxPoses = 200000;
constexpr double kMinBlockFactor = 0.8;  ///< rung spacing = preferred x [0.8, 1.2] (clamped)
constexpr double kMaxBlockFactor = 1.2;
/// Rows are this many times the rung spacing apart on a 4 km route (more on longer ones), so the
/// city is a block of streets rather than a strip.
constexpr double kRowSpacingFactor = 2.5;
/// Widths are scaled down from their drawn values (1) towards the minimum (0) only when a short
/// route cannot fit full-size streets.
constexpr double kSizeFactors[] = {1.0, 0.75, 0.5, 0.25, 0.0};

/// Independent random streams (the street layouts use streams of their own).
enum Stream : std::uint64_t {
    kRowLine = 0x10000,
    kRungLine = 0x20000,
    kBlockSpacing = 0x30000,
    kRowBlock = 0x40000,
    kRungBlock = 0x50000,
    kDrive = 0x60000,
};

double snap(double value_m) { return std::round(value_m / kGrid_m) * kGrid_m; }
double snap_up(double value_m) { return std::ceil(value_m / kGrid_m - 1e-9) * kGrid_m; }

/// A line's random width fractions, drawn per line so that they do not depend on W.
struct LineFractions {
    double road, sidewalk, lot;
};

LineFractions draw_line(std::uint64_t seed, std::uint64_t stream) {
    Rng rng(derive_seed(seed, stream));
    LineFractions f;
    f.road = rng.uniform(0.0, 1.0);
    f.sidewalk = rng.uniform(0.0, 1.0);
    f.lot = rng.uniform(0.0, 1.0);
    return f;
}

StreetLine make_line(const LineFractions& f, double size_factor) {
    StreetLine line;
    line.half_road_m = snap(5.0 + 2.0 * size_factor * f.road);           // roads 10 .. 14 m
    line.sidewalk_width_m = snap(2.5 + 2.0 * size_factor * f.sidewalk);  // 2.5 .. 4.5 m
    line.lot_depth_m = snap(12.0 + 8.0 * size_factor * f.lot);           // 12 .. 20 m
    return line;
}

/// The street lines of a city with W + 1 rungs whose spacing aims at `block_m`.
struct Lines {
    std::vector<StreetLine> rungs, rows;
};

Lines lay_out_lines(std::uint64_t seed, int W, double size_factor, double block_m,
                    double row_spacing_factor) {
    Lines lines;
    for (int j = 0; j < 2; ++j) {
        lines.rows.push_back(make_line(draw_line(seed, kRowLine + j), size_factor));
    }
    for (int k = 0; k <= W; ++k) {
        lines.rungs.push_back(make_line(draw_line(seed, kRungLine + k), size_factor));
    }
    lines.rungs[0].center_m = 0.0;
    for (int i = 0; i < W; ++i) {
        const StreetLine& a = lines.rungs[i];
        StreetLine& b = lines.rungs[i + 1];
        const double factor =
            Rng(derive_seed(seed, kBlockSpacing + i)).uniform(kMinBlockFactor, kMaxBlockFactor);
        // The rungs' lots must not meet, and the row's street between their sidewalks must be
        // long enough for make_street_scene.
        const double min_spacing_m =
            snap_up(std::max(a.lot_outer_m() + b.lot_outer_m() + kLotGap_m,
                             a.curb_outer_m() + b.curb_outer_m() + kMinStreetLength_m));
        b.center_m = a.center_m + std::max(min_spacing_m, snap(factor * block_m));
    }
    const StreetLine& row0 = lines.rows[0];
    lines.rows[0].center_m = 0.0;
    lines.rows[1].center_m =
        std::max(snap_up(row0.lot_outer_m() + lines.rows[1].lot_outer_m() + kMinStreetLength_m),
                 snap(row_spacing_factor * block_m));
    return lines;
}

const Eigen::Vector2d kEast(1.0, 0.0), kWest(-1.0, 0.0), kNorth(0.0, 1.0), kSouth(0.0, -1.0);

/// A 90-degree turn of the drive: from heading `in` to heading `out` at `point`, the crossing of
/// the two lane centre lines.
struct Corner {
    Eigen::Vector2d point, in, out;
};

/// Right-hand traffic: the lane centre lies lane_from_curb_m inside the right-hand curb.
Corner make_corner(const StreetLine& rung, const StreetLine& row, const Eigen::Vector2d& in,
                   const Eigen::Vector2d& out, double lane_from_curb_m) {
    const Eigen::Vector2d& along_rung = in.x() == 0.0 ? in : out;
    const Eigen::Vector2d& along_row = in.x() == 0.0 ? out : in;
    const double rung_offset_m = rung.half_road_m - lane_from_curb_m;
    const double row_offset_m = row.half_road_m - lane_from_curb_m;
    // Right of heading (dx, dy) is (dy, -dx).
    const double x = rung.center_m + (along_rung.y() > 0.0 ? rung_offset_m : -rung_offset_m);
    const double y = row.center_m + (along_row.x() > 0.0 ? -row_offset_m : row_offset_m);
    return {Eigen::Vector2d(x, y), in, out};
}

/// The loop's corners in driving order, starting with the turn at the end of row 0.
std::vector<Corner> loop_corners(const Lines& lines, double lane_from_curb_m) {
    const int W = static_cast<int>(lines.rungs.size()) - 1;
    const StreetLine& row0 = lines.rows[0];
    const StreetLine& row1 = lines.rows[1];
    std::vector<Corner> corners;
    auto add = [&](int k, const StreetLine& row, const Eigen::Vector2d& in,
                   const Eigen::Vector2d& out) {
        corners.push_back(make_corner(lines.rungs[k], row, in, out, lane_from_curb_m));
    };
    add(W, row0, kEast, kNorth);
    add(W, row1, kNorth, kWest);
    for (int k = W - 1; k >= 0; --k) {
        if ((W - k) % 2 == 1) {  // south down rung k
            add(k, row1, kWest, kSouth);
            add(k, row0, kSouth, k > 0 ? kWest : kEast);
        } else {  // north up rung k
            add(k, row0, kWest, kNorth);
            add(k, row1, kNorth, kWest);
        }
    }
    return corners;
}

/// Straights between quarter-circle fillets of radius `radius_m`; starts where the last corner's
/// turn ends. Returns false (and no path) if two corners are closer than their fillets need.
bool make_loop(const std::vector<Corner>& corners, double radius_m, LoopPath& loop) {
    std::vector<PathPiece> pieces;
    Eigen::Vector2d previous_end = corners.back().point + radius_m * corners.back().out;
    for (const Corner& c : corners) {
        const Eigen::Vector2d arc_start = c.point - radius_m * c.in;
        const double straight_m = (arc_start - previous_end).dot(c.in);
        if (straight_m < 0.0) return false;
        PathPiece straight;
        straight.start_m = previous_end;
        straight.direction = c.in;
        straight.length_m = straight_m;
        pieces.push_back(straight);
        PathPiece arc;
        arc.start_m = arc_start;
        arc.direction = c.in;
        arc.length_m = 0.5 * M_PI * radius_m;
        arc.turn = c.in.x() * c.out.y() - c.in.y() * c.out.x() > 0.0 ? 1 : -1;
        arc.radius_m = radius_m;
        pieces.push_back(arc);
        previous_end = c.point + radius_m * c.out;
    }
    loop = LoopPath(std::move(pieces));
    return true;
}

/// The whole drive's length for a layout: the loop plus the revisit of the first street. +inf if
/// the layout cannot hold the loop.
struct Candidate {
    Lines lines;
    LoopPath loop;
    double revisit_m = 0.0;  ///< the first street and revisit_beyond_m past its end
    double total_m = std::numeric_limits<double>::infinity();
};

Candidate evaluate(const CityRouteConfig& config, std::uint64_t seed, int W, double size_factor,
                   double block_m, double row_spacing_factor) {
    Candidate c;
    c.lines = lay_out_lines(seed, W, size_factor, block_m, row_spacing_factor);
    if (!make_loop(loop_corners(c.lines, config.lane_from_curb_m), config.turn_radius_m, c.loop)) {
        return c;
    }
    c.revisit_m =
        c.lines.rungs[1].center_m + config.revisit_beyond_m - c.loop.pieces().front().start_m.x();
    c.total_m = c.loop.length_m() + c.revisit_m;
    return c;
}

/// Street of a block in one of three styles; heights are kept moderate because the LiDAR's top
/// beam (+2 deg) sees no higher than ~5 m, so taller walls would only add triangles.
StreetSceneConfig styled_street(const StreetSceneConfig& base, const StreetLine& line,
                                double length_m, std::uint64_t block_seed, std::string& style) {
    StreetSceneConfig s = base;
    s.seed = derive_seed(block_seed, 1);
    s.start_x_m = 0.0;
    s.length_m = length_m;
    s.road_width_m = 2.0 * line.half_road_m;
    s.sidewalk_width_m = line.sidewalk_width_m;
    s.lot_depth_m = line.lot_depth_m;
    Rng rng(derive_seed(block_seed, 2));
    const double pick = rng.uniform(0.0, 1.0);
    if (pick < 0.35) {
        style = "residential";  // low houses behind front gardens, many trees
        s.building_height_min_m = rng.uniform(4.0, 6.0);
        s.building_height_max_m = rng.uniform(8.0, 12.0);
        s.building_setback_max_m = rng.uniform(2.5, 6.0);
        s.building_gap_min_m = rng.uniform(2.0, 3.0);
        s.building_gap_max_m = rng.uniform(6.0, 10.0);
        s.tree_spacing_m = rng.uniform(7.0, 10.0);
        s.pole_spacing_m = rng.uniform(22.0, 30.0);
        s.car_spacing_m = rng.uniform(7.5, 10.0);
        s.pedestrians_per_100m = rng.uniform(3.0, 8.0);
    } else if (pick < 0.75) {
        style = "mixed";  // the bundled street's mix
        s.building_height_min_m = rng.uniform(5.0, 8.0);
        s.building_height_max_m = rng.uniform(14.0, 20.0);
        s.building_setback_max_m = rng.uniform(1.0, 3.0);
        s.building_gap_min_m = rng.uniform(1.0, 2.0);
        s.building_gap_max_m = rng.uniform(4.0, 7.0);
        s.tree_spacing_m = rng.uniform(10.0, 14.0);
        s.pole_spacing_m = rng.uniform(18.0, 24.0);
        s.car_spacing_m = rng.uniform(8.0, 10.0);
        s.pedestrians_per_100m = rng.uniform(8.0, 14.0);
    } else {
        style = "downtown";  // tall, close-set buildings at the sidewalk, few trees
        s.building_height_min_m = rng.uniform(9.0, 12.0);
        s.building_height_max_m = rng.uniform(20.0, 26.0);
        s.building_setback_max_m = rng.uniform(0.0, 1.0);
        s.building_gap_min_m = rng.uniform(0.5, 1.5);
        s.building_gap_max_m = rng.uniform(2.0, 4.0);
        s.tree_spacing_m = rng.uniform(14.0, 22.0);
        s.pole_spacing_m = rng.uniform(15.0, 20.0);
        s.car_spacing_m = rng.uniform(9.0, 14.0);
        s.pedestrians_per_100m = rng.uniform(15.0, 25.0);
    }
    return s;
}

Eigen::Vector2d left_of(const Eigen::Vector2d& heading) { return {-heading.y(), heading.x()}; }

/// Position and heading `u_m` along a piece.
void point_on_piece(const PathPiece& p, double u_m, Eigen::Vector2d& position_m,
                    Eigen::Vector2d& heading) {
    if (p.turn == 0) {
        position_m = p.start_m + u_m * p.direction;
        heading = p.direction;
        return;
    }
    const Eigen::Vector2d center = p.start_m + p.turn * p.radius_m * left_of(p.direction);
    const Eigen::Rotation2Dd rotation(p.turn * u_m / p.radius_m);
    position_m = center + rotation * (p.start_m - center);
    heading = rotation * p.direction;
}

}  // namespace city_internal

using namespace city_internal;

LoopPath::LoopPath(std::vector<PathPiece> pieces) : pieces_(std::move(pieces)) {
    start_s_m_.reserve(pieces_.size());
    for (std::size_t i = 0; i < pieces_.size(); ++i) {
        const PathPiece& p = pieces_[i];
        if (!(p.length_m >= 0.0) || (p.turn != 0 && !(p.radius_m > 0.0))) {
            throw ConfigError("route path: piece " + std::to_string(i) + " has length " +
                              std::to_string(p.length_m) + " m and radius " +
                              std::to_string(p.radius_m) + " m; both must be positive");
        }
        start_s_m_.push_back(length_m_);
        length_m_ += p.length_m;
    }
    // The pieces must join: each ends where the next starts, heading the same way.
    for (std::size_t i = 0; i < pieces_.size(); ++i) {
        Eigen::Vector2d end_m, heading;
        point_on_piece(pieces_[i], pieces_[i].length_m, end_m, heading);
        const PathPiece& next = pieces_[(i + 1) % pieces_.size()];
        if ((end_m - next.start_m).norm() > 1e-6 || (heading - next.direction).norm() > 1e-9) {
            throw ConfigError("route path: piece " + std::to_string(i) +
                              " does not end where the next one starts");
        }
    }
}

void LoopPath::sample(double s_m, Eigen::Vector2d& position_m, Eigen::Vector2d& heading) const {
    if (pieces_.empty()) {
        position_m.setZero();
        heading = Eigen::Vector2d::UnitX();
        return;
    }
    double s = std::fmod(s_m, length_m_);
    if (s < 0.0) s += length_m_;
    const auto it = std::upper_bound(start_s_m_.begin(), start_s_m_.end(), s);
    const std::size_t index = static_cast<std::size_t>(it - start_s_m_.begin()) - 1;
    const PathPiece& p = pieces_[index];
    point_on_piece(p, std::min(s - start_s_m_[index], p.length_m), position_m, heading);
}

void validate(const CityRouteConfig& c) {
    auto require = [](bool ok, const std::string& key, double value, const std::string& rule) {
        if (!ok) {
            throw ConfigError("city route: " + key + " = " + std::to_string(value) + " " + rule);
        }
    };
    require(c.route_length_m > 0.0 && c.route_length_m <= kMaxRouteLength_m, "route_length_m",
            c.route_length_m, "must be in (0, 20000] (the drive's length; 4000 is like KITTI 00)");
    require(c.preferred_block_length_m >= 40.0 && c.preferred_block_length_m <= 1000.0,
            "preferred_block_length_m", c.preferred_block_length_m, "must be in [40, 1000]");
    require(c.turn_radius_m >= 4.0 && c.turn_radius_m <= 15.0, "turn_radius_m", c.turn_radius_m,
            "must be in [4, 15] (corners must fit inside the junctions)");
    require(c.lane_from_curb_m >= 2.5 && c.lane_from_curb_m <= 5.0, "lane_from_curb_m",
            c.lane_from_curb_m, "must be in [2.5, 5] (roads are at least 10 m wide)");
    require(c.revisit_beyond_m >= 0.0 && c.revisit_beyond_m <= 100.0, "revisit_beyond_m",
            c.revisit_beyond_m, "must be in [0, 100]");
    StreetSceneConfig street = c.street;
    street.length_m = 100.0;  // set per block
    validate(street);
}

CityRoute make_city_route(const CityRouteConfig& config, std::uint64_t seed) {
    validate(config);
    const double L = config.route_length_m;
    const double row_spacing_factor = kRowSpacingFactor * std::max(1.0, std::sqrt(L / 4000.0));
    // The largest street size that fits, then the W whose mean block is nearest the preferred one;
    // for each W the rung spacing is found by bisection (the drive's length grows with it).
    Candidate best;
    double best_score = std::numeric_limits<double>::infinity();
    double size_factor = 1.0;
    for (const double size : kSizeFactors) {
        for (int W = 1;; W += 2) {
            if (evaluate(config, seed, W, size, 0.0, row_spacing_factor).total_m > L) break;
            double lo = 0.0, hi = L;
            for (int iteration = 0; iteration < 60; ++iteration) {
                const double mid = 0.5 * (lo + hi);
                (evaluate(config, seed, W, size, mid, row_spacing_factor).total_m <= L ? lo : hi) =
                    mid;
            }
            Candidate c = evaluate(config, seed, W, size, lo, row_spacing_factor);
            const double mean_block_m = c.lines.rungs.back().center_m / W;
            const double score = std::abs(mean_block_m - config.preferred_block_length_m);
            if (score < best_score) {
                best_score = score;
                best = std::move(c);
            }
        }
        if (std::isfinite(best.total_m)) {
            size_factor = size;
            break;
        }
    }
    if (!std::isfinite(best.total_m)) {
        const double shortest_m = evaluate(config, seed, 1, 0.0, 0.0, row_spacing_factor).total_m;
        char buffer[256];
        std::snprintf(buffer, sizeof(buffer),
                      "city route: a route of %.3f km is too short; the smallest city for seed "
                      "%llu (one block around, then its first street again) needs %.3f km",
                      L / 1000.0, static_cast<unsigned long long>(seed), shortest_m / 1000.0);
        throw ConfigError(buffer);
    }

    CityRoute route;
    route.street = config.street;
    route.rungs = best.lines.rungs;
    route.rows = best.lines.rows;
    route.loop = best.loop;
    route.route_length_m = L;
    route.revisit_length_m = L - best.loop.length_m();
    route.first_street_end_m = route.rungs[1].center_m - best.loop.pieces().front().start_m.x();
    route.size_factor = size_factor;
    const int W = static_cast<int>(route.rungs.size()) - 1;

    // Row blocks run between the rungs' sidewalks: all of row 0, and the blocks of row 1 the
    // meander drives (between rungs k and k + 1 for even k).
    auto row_block_built = [&](int row, int i) {
        return i >= 0 && i < W && (row == 0 || i % 2 == 0);
    };
    for (int row = 0; row < 2; ++row) {
        for (int i = 0; i < W; ++i) {
            if (!row_block_built(row, i)) continue;
            const StreetLine& line = route.rows[row];
            const double x0 = route.rungs[i].center_m + route.rungs[i].curb_outer_m();
            const double x1 = route.rungs[i + 1].center_m - route.rungs[i + 1].curb_outer_m();
            StreetSegment segment;
            segment.along_y = false;
            segment.line = row;
            segment.origin_m = Eigen::Vector2d(x0, line.center_m);
            segment.scene =
                styled_street(route.street, line, x1 - x0,
                              derive_seed(seed, kRowBlock + 1000 * row + i), segment.style);
            route.segments.push_back(segment);
        }
    }
    // Rungs run between the rows' lots.
    for (int k = 0; k <= W; ++k) {
        const StreetLine& line = route.rungs[k];
        const double y0 = route.rows[0].center_m + route.rows[0].lot_outer_m();
        const double y1 = route.rows[1].center_m - route.rows[1].lot_outer_m();
        StreetSegment segment;
        segment.along_y = true;
        segment.line = k;
        segment.origin_m = Eigen::Vector2d(line.center_m, y0);
        segment.scene = styled_street(route.street, line, y1 - y0,
                                      derive_seed(seed, kRungBlock + k), segment.style);
        route.segments.push_back(segment);
    }
    for (int row = 0; row < 2; ++row) {
        for (int k = 0; k <= W; ++k) {
            Junction j;
            j.rung = k;
            j.row = row;
            j.arm_west = row_block_built(row, k - 1);
            j.arm_east = row_block_built(row, k);
            j.arm_north = row == 0;
            j.arm_south = row == 1;
            const StreetLine& rung = route.rungs[k];
            const StreetLine& line = route.rows[row];
            const double west_m = j.arm_west ? rung.curb_outer_m() : rung.lot_outer_m();
            const double east_m = j.arm_east ? rung.curb_outer_m() : rung.lot_outer_m();
            j.area_m = Eigen::AlignedBox2d(
                Eigen::Vector2d(rung.center_m - west_m, line.center_m - line.lot_outer_m()),
                Eigen::Vector2d(rung.center_m + east_m, line.center_m + line.lot_outer_m()));
            route.junctions.push_back(j);
        }
    }
    return route;
}

DriveTrajectoryConfig default_route_trajectory() {
    DriveTrajectoryConfig t;
    t.frame_spacing_m = 1.6;
    t.weave_amplitude_m = 0.3;
    t.weave_wavelength_m = 60.0;
    return t;
}

std::vector<Eigen::Isometry3d> make_route_poses(const CityRoute& route,
                                                const DriveTrajectoryConfig& trajectory,
                                                std::uint64_t seed) {
    validate(trajectory);
    if (trajectory.weave_amplitude_m > 1.0) {
        throw ConfigError(
            "trajectory: weave_amplitude_m = " + std::to_string(trajectory.weave_amplitude_m) +
            " must be <= 1 on a city route (the car keeps clear of parked cars)");
    }
    const double n_poses =
        std::floor(route.route_length_m / trajectory.frame_spacing_m + 1e-9) + 1.0;
    if (!(n_poses <= kMaxPoses)) {
        throw ConfigError("route: " + std::to_string(route.route_length_m) + " m with " +
                          std::to_string(trajectory.frame_spacing_m) + " m between scans are " +
                          std::to_string(static_cast<long long>(n_poses)) +
                          " scans, more than 200000; choose a larger frame spacing");
    }
    Rng rng(derive_seed(seed, kDrive));
    const double weave_phase = rng.uniform(0.0, 2.0 * M_PI);
    const double pitch_phase = rng.uniform(0.0, 2.0 * M_PI);
    const double roll_phase = rng.uniform(0.0, 2.0 * M_PI);
    constexpr double kPitchWavelength_m = 17.0;  // as make_drive_trajectory
    constexpr double kRollWavelength_m = 11.0;
    constexpr double kDegToRad = M_PI / 180.0;
    const double k = 2.0 * M_PI / trajectory.weave_wavelength_m;
    std::vector<Eigen::Isometry3d> poses;
    poses.reserve(static_cast<std::size_t>(n_poses));
    for (int i = 0; i < static_cast<int>(n_poses); ++i) {
        const double s = i * trajectory.frame_spacing_m;
        Eigen::Vector2d position_m, heading;
        route.loop.sample(s, position_m, heading);
        const double weave_m = trajectory.weave_amplitude_m * std::sin(k * s + weave_phase);
        const double weave_slope = trajectory.weave_amplitude_m * k * std::cos(k * s + weave_phase);
        position_m += weave_m * left_of(heading);
        const double yaw = std::atan2(heading.y(), heading.x()) + std::atan(weave_slope);
        const double pitch = trajectory.pitch_amplitude_deg * kDegToRad *
                             std::sin(2.0 * M_PI * s / kPitchWavelength_m + pitch_phase);
        const double roll = trajectory.roll_amplitude_deg * kDegToRad *
                            std::sin(2.0 * M_PI * s / kRollWavelength_m + roll_phase);
        Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
        T_world_sensor.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                   Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                                   Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                                      .toRotationMatrix();
        T_world_sensor.translation() =
            Eigen::Vector3d(position_m.x(), position_m.y(), trajectory.sensor_height_m);
        poses.push_back(T_world_sensor);
    }
    return poses;
}

}  // namespace shine::sim
