#include "shine/sim/route_simulation.hpp"

#include <algorithm>
#include <chrono>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "sequence_files.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/core/stopwatch.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/ply.hpp"
#include "shine/sim/block_ray_caster.hpp"
#include "shine/sim/city_scene.hpp"
#include "shine/sim/moving_scene.hpp"
#include "shine/sim/route_movers.hpp"
#include "sim_random.hpp"

namespace shine::sim {
namespace route_internal {

using random_internal::derive_seed;
using sequence_internal::format_frame;
using sequence_internal::json_number;

/// Independent random streams (the city and the drive use streams of their own).
enum Stream : std::uint64_t { kNoise = 0x200, kMovers = 0x300 };

std::string line_name(const StreetSegment& s) {
    return (s.along_y ? "rung " : "row ") + std::to_string(s.line);
}

}  // namespace route_internal

using namespace route_internal;

void validate(const RouteSimulationConfig& config) {
    if (!config.origin_offset_world_m.allFinite() ||
        config.origin_offset_world_m.cwiseAbs().maxCoeff() > 1e9) {
        throw ConfigError(
            "route simulation: origin_offset_world_m must be finite and within 1e9 m");
    }
    validate(config.city);
    validate(config.trajectory);
    validate(config.lidar);
    validate(config.movers);
}

RouteSimulationSummary simulate_route_sequence(const RouteSimulationConfig& config,
                                               const std::filesystem::path& out_dir) {
    namespace fs = std::filesystem;
    validate(config);
    const auto start = std::chrono::steady_clock::now();

    const CityRoute route = make_city_route(config.city, config.seed);
    const std::vector<Eigen::Isometry3d> poses =
        make_route_poses(route, config.trajectory, config.seed);
    const int num_frames = static_cast<int>(poses.size());

    RouteSimulationSummary result;
    result.route_length_m = route.route_length_m;
    result.loop_length_m = route.loop.length_m();
    result.num_rungs = static_cast<int>(route.rungs.size());
    result.num_streets = route.segments.size();
    result.num_junctions = route.junctions.size();
    SimulationSummary& summary = result.sequence;
    summary.num_frames = num_frames;

    auto phase_start = std::chrono::steady_clock::now();
    CityScene city = make_city_scene(route, config.show_progress);
    result.scene_seconds = seconds_since(phase_start);
    TriangleMesh& mesh = city.scene.mesh;
    summary.num_triangles = mesh.triangles.size();

    const fs::path velodyne_dir = out_dir / "velodyne";
    ensure_directory(velodyne_dir);
    sequence_internal::remove_stale_scans(velodyne_dir, num_frames);

    MoverTracks movers;
    {
        // The BVHs live only while scanning: writing gt_mesh.ply needs a buffer of the file's size.
        phase_start = std::chrono::steady_clock::now();
        const BlockRayCaster caster(mesh, city.blocks, config.show_progress);
        result.index_seconds = seconds_since(phase_start);
        const auto noise_seed = [&](int frame) {
            return derive_seed(config.seed, kNoise + static_cast<std::uint64_t>(frame));
        };
        if (config.movers.num_movers > 0) {
            movers = make_route_movers(config.movers, route, config.trajectory, num_frames,
                                       obstacle_footprints(city.scene),
                                       derive_seed(config.seed, kMovers));
            const MovingScene moving(caster, movers);
            sequence_internal::simulate_and_write_scans(
                moving, config.lidar, poses, noise_seed, config.origin_offset_world_m,
                config.show_progress, out_dir, mesh, summary);
        } else {
            sequence_internal::simulate_and_write_scans(
                caster, config.lidar, poses, noise_seed, config.origin_offset_world_m,
                config.show_progress, out_dir, mesh, summary);
        }
    }
    result.num_movers = movers.movers.size();
    write_ply_mesh(out_dir / "gt_mesh.ply", mesh);

    // Parameters, for people (README.txt) and programs (simulation.json).
    const auto& l = config.lidar;
    const auto& t = config.trajectory;
    const auto& c = config.city;
    Eigen::AlignedBox2d extent;
    for (const Junction& j : route.junctions) extent.extend(j.area_m);
    const Eigen::Vector2d size_m = extent.sizes();
    std::ostringstream json;
    sequence_internal::write_simulation_json_head(json, "shine simulate --route-km", config.seed,
                                                  num_frames, config.origin_offset_world_m, l, t);
    json << "  \"route\": {\"length_m\": " << json_number(route.route_length_m)
         << ", \"loop_length_m\": " << json_number(route.loop.length_m())
         << ", \"revisit_length_m\": " << json_number(route.revisit_length_m)
         << ", \"first_street_end_m\": " << json_number(route.first_street_end_m)
         << ", \"turn_radius_m\": " << json_number(c.turn_radius_m)
         << ", \"lane_from_curb_m\": " << json_number(c.lane_from_curb_m)
         << ", \"size_factor\": " << json_number(route.size_factor)
         << ", \"rungs\": " << route.rungs.size() << ", \"rows\": " << route.rows.size()
         << ", \"row_spacing_m\": " << json_number(route.rows[1].center_m - route.rows[0].center_m)
         << ", \"extent_m\": [" << json_number(size_m.x()) << ", " << json_number(size_m.y())
         << "], \"junctions\": " << route.junctions.size() << "},\n"
         << "  \"streets\": [\n";
    for (std::size_t i = 0; i < route.segments.size(); ++i) {
        const StreetSegment& s = route.segments[i];
        const StreetSceneConfig& sc = s.scene;
        json << "    {\"line\": \"" << line_name(s) << "\", \"along\": \""
             << (s.along_y ? 'y' : 'x') << "\", \"start_m\": [" << json_number(s.origin_m.x())
             << ", " << json_number(s.origin_m.y())
             << "], \"length_m\": " << json_number(sc.length_m) << ", \"style\": \"" << s.style
             << "\", \"road_width_m\": " << json_number(sc.road_width_m)
             << ", \"sidewalk_width_m\": " << json_number(sc.sidewalk_width_m)
             << ", \"lot_depth_m\": " << json_number(sc.lot_depth_m) << ", \"building_height_m\": ["
             << json_number(sc.building_height_min_m) << ", "
             << json_number(sc.building_height_max_m)
             << "], \"building_setback_max_m\": " << json_number(sc.building_setback_max_m) << "}"
             << (i + 1 < route.segments.size() ? "," : "") << "\n";
    }
    json << "  ],\n"
         << "  \"scene\": {\"curb_height_m\": " << json_number(route.street.curb_height_m)
         << ", \"max_edge_length_m\": " << json_number(route.street.max_edge_length_m)
         << ", \"objects\": {";
    sequence_internal::write_simulation_json_tail(
        json, city.scene, summary,
        movers.movers.empty() ? "" : "  \"movers\": " + mover_tracks_to_json(movers) + ",\n");
    write_stream_atomically(out_dir / "simulation.json",
                            [&](std::ostream& out) { out << json.str(); });
    write_stream_atomically(out_dir / "README.txt", [&](std::ostream& out) {
        out << "Simulated LiDAR sequence written by `shine simulate --route-km` (ShineVDB).\n\n"
            << "Scene: a procedural city (seed " << config.seed << "), z up, roads at z = 0, "
            << size_m.x() << " x " << size_m.y() << " m: two streets along x joined by "
            << route.rungs.size() << " cross streets,\n"
            << route.segments.size() << " street blocks and " << route.junctions.size()
            << " junctions; " << summary.num_triangles << " triangles, no edge longer than "
            << route.street.max_edge_length_m << " m.\n"
            << "Drive: " << route.route_length_m / 1000.0
            << " km on the right-hand lane: east along the first street (y = 0), back west in a\n"
            << "meander over the cross streets, and through the first street again (the last "
            << route.revisit_length_m << " m\nretrace the first ones: a loop closure).\n"
            << "Sensor: " << l.num_beams << " beams from " << l.elevation_max_deg << " to "
            << l.elevation_min_deg << " deg, " << l.azimuth_steps << " azimuth steps, range "
            << l.min_range_m << " - " << l.max_range_m << " m, Gaussian range noise sigma "
            << l.range_noise_sigma_m << " m,\nmounted " << t.sensor_height_m
            << " m above the road; " << num_frames << " scans, " << t.frame_spacing_m
            << " m apart along the drive.\n\n"
            << (movers.movers.empty()
                    ? std::string()
                    : "Movers: " + std::to_string(movers.movers.size()) +
                          " cars, cyclists and pedestrians on the straights of the drive, each "
                          "present\nonly while the sensor drives its stretch "
                          "(simulation.json, \"movers\"); gt_mesh.ply holds the\nstatic city "
                          "only.\n\n")
            << "velodyne/NNNNNN.bin  float32 x y z intensity (0) per point, sensor frame\n"
            << "poses.txt            T_world_sensor per frame, 12 numbers (3x4 row-major)\n"
            << "gt_mesh.ply          reference mesh in the world frame; face property "
               "`observed` = 1\n"
            << "                     for the " << summary.num_observed_triangles
            << " triangles that at least one ray hit\n"
            << "simulation.json      all parameters (every street block) and counts\n";
    });
    summary.seconds = seconds_since(start);
    return result;
}

}  // namespace shine::sim
