// A procedural city and a long drive through it with a loop back to the start, for testing
// mapping at city scale (think KITTI sequence 00: 3.7 km that end where they began).
//
// The city is a ladder of streets: two rows along world x (row 0 at y = 0, row 1 north of it)
// joined by W + 1 cross streets along y, the rungs (W odd, at x = X_0 = 0 < X_1 < ... < X_W).
// The drive, on the right-hand lane:
//   1. east along all of row 0, straight through its T-junctions (its first block is the "first
//      street");
//   2. back west in a meander: north up rung W, west along row 1, south down rung W-1, west along
//      row 0, north up rung W-2, ..., south down rung 0;
//   3. left into row 0 again: the revisit drives the first street once more and stops a little
//      past the junction at its end.
// Every street that is built is driven (the meander's blocks of row 0 twice, once each way); the
// blocks of row 1 the meander skips are not built, so their junctions are corners. Each street
// line has its own road, sidewalk and lot widths (junctions need one cross-section per line); each
// block has its own style: building heights, setbacks and gaps, trees, poles, parked cars. The
// rungs' spacing varies block by block.
//
// Where the pieces meet: a rung's street runs between the two rows' lots; a row's street runs
// between the rungs' sidewalks, so its lots take the corners; a junction is ground only (road arms
// towards the streets that exist, sidewalks and empty lots elsewhere). Lines sit on a 1/8 m grid,
// so streets and junctions meet on float-exact coordinates.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <string>
#include <vector>

#include "shine/sim/drive_trajectory.hpp"
#include "shine/sim/street_scene.hpp"

namespace shine::sim {

/// Cross-section of a street line; all its blocks and junctions share it. Lengths in metres.
struct StreetLine {
    double center_m = 0.0;  ///< world x of a rung, world y of a row
    double half_road_m = 5.0;
    double sidewalk_width_m = 3.0;
    double lot_depth_m = 17.0;

    /// Distance of the sidewalk's outer edge from the centre line.
    double curb_outer_m() const { return half_road_m + sidewalk_width_m; }
    /// Distance of the lots' outer edge from the centre line.
    double lot_outer_m() const { return half_road_m + sidewalk_width_m + lot_depth_m; }
};

/// One block of street between two junctions: make_street_scene(scene) moved into place.
struct StreetSegment {
    StreetSceneConfig scene;  ///< start_x_m = 0, length_m = the block's length; seed, style set
    bool along_y = false;     ///< false: a row block, street x = world x; true: a rung block,
                              ///< street x = world y and street y = -world x
    Eigen::Vector2d origin_m = Eigen::Vector2d::Zero();  ///< world x-y of the street frame origin
    int line = 0;       ///< index into CityRoute::rows (a row block) or CityRoute::rungs
    std::string style;  ///< "residential", "mixed" or "downtown"
};

/// The junction of rung `rung` and row `row`: ground over `area_m` (world x-y), road towards the
/// arms that exist.
struct Junction {
    int rung = 0;
    int row = 0;
    bool arm_west = false;
    bool arm_east = false;
    bool arm_south = false;
    bool arm_north = false;
    Eigen::AlignedBox2d area_m;
};

/// A piece of the drive's path: a straight line or a quarter circle.
struct PathPiece {
    Eigen::Vector2d start_m = Eigen::Vector2d::Zero();
    Eigen::Vector2d direction = Eigen::Vector2d::UnitX();  ///< unit heading at the start
    double length_m = 0.0;
    int turn = 0;           ///< 0: straight, +1: left (counter-clockwise), -1: right
    double radius_m = 0.0;  ///< of an arc
};

/// A closed path with a continuous heading, parametrised by arc length.
class LoopPath {
  public:
    LoopPath() = default;
    /// Throws ConfigError if a piece has a negative length or the pieces do not join up.
    explicit LoopPath(std::vector<PathPiece> pieces);

    double length_m() const { return length_m_; }
    const std::vector<PathPiece>& pieces() const { return pieces_; }
    /// Position and unit heading at arc length `s_m`, taken modulo length_m().
    void sample(double s_m, Eigen::Vector2d& position_m, Eigen::Vector2d& heading) const;

  private:
    std::vector<PathPiece> pieces_;
    std::vector<double> start_s_m_;
    double length_m_ = 0.0;
};

/// Parameters of the city and its drive. Lengths in metres.
struct CityRouteConfig {
    double route_length_m = 4000.0;           ///< the drive: the loop, then its first street again
    double preferred_block_length_m = 110.0;  ///< mean rung spacing aimed at (drawn ±20 % a block)
    double turn_radius_m = 8.0;               ///< of the drive's lane at every corner
    double lane_from_curb_m = 4.5;   ///< lane centre from the right-hand curb (min. half road 5 m)
    double revisit_beyond_m = 10.0;  ///< the revisit ends this far past the first street's end
    StreetSceneConfig street;  ///< curb height and max edge of every street; the rest is drawn
};

/// Throws ConfigError naming the field if a value is out of range.
void validate(const CityRouteConfig& config);

/// A city and its drive.
struct CityRoute {
    StreetSceneConfig street;             ///< the base street (curb height, max edge)
    std::vector<StreetLine> rungs;        ///< W + 1 lines along y
    std::vector<StreetLine> rows;         ///< 2 lines along x
    std::vector<StreetSegment> segments;  ///< row 0 blocks, row 1 blocks, rungs
    std::vector<Junction> junctions;
    LoopPath loop;                    ///< starts on the first street (row 0) heading +x
    double route_length_m = 0.0;      ///< the drive: loop.length_m() + revisit_length_m
    double revisit_length_m = 0.0;    ///< the drive ends by retracing the loop's first metres
    double first_street_end_m = 0.0;  ///< arc length of the first street's end (junction centre)
    double size_factor = 1.0;  ///< 1, or down to 0 when the route is too short for wide streets
};

/// Lays out the city for config.route_length_m: picks W and the rung spacing so that the drive is
/// exactly that long with blocks near preferred_block_length_m. Deterministic for a seed. Throws
/// ConfigError if the route is shorter than the smallest city allows (one block around, about
/// 0.25 km) and names that length.
CityRoute make_city_route(const CityRouteConfig& config, std::uint64_t seed);

/// Sensor poses T_world_sensor along the drive, one every trajectory.frame_spacing_m of arc length
/// from its start to route_length_m, with the lateral weave, pitch and roll of
/// make_drive_trajectory (phases from `seed`, functions of the distance driven, so the revisit
/// differs slightly from the first pass). Throws ConfigError for an invalid trajectory or more
/// than 200000 poses.
std::vector<Eigen::Isometry3d> make_route_poses(const CityRoute& route,
                                                const DriveTrajectoryConfig& trajectory,
                                                std::uint64_t seed);

/// The trajectory defaults of a route: 1.6 m between scans (a 4 km route: 2501 scans; KITTI 00
/// has ~0.8 m at 10 Hz) and a gentler weave than the street's, so the car keeps to its lane.
DriveTrajectoryConfig default_route_trajectory();

}  // namespace shine::sim
