#include "shine/io/mover_tracks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <sstream>

#include "shine/core/error.hpp"
#include "shine/io/file_contents.hpp"

namespace shine {
namespace mover_tracks_internal {

using nlohmann::json;

/// Parsing context: the file and the key path, for messages.
struct Where {
    const std::filesystem::path& source;
    std::string key;

    [[noreturn]] void fail(const std::string& problem) const {
        throw DataError("mover tracks '" + source.string() + "': " + key + " " + problem +
                        " (write it with `shine simulate --movers N`)");
    }
    Where at(const std::string& child) const { return {source, key + "." + child}; }
    Where at(std::size_t index) const { return {source, key + "[" + std::to_string(index) + "]"}; }
};

const json& member(const json& object, const char* name, const Where& where) {
    if (!object.is_object()) where.fail("must be an object");
    const auto it = object.find(name);
    if (it == object.end()) where.at(name).fail("is missing");
    return *it;
}

double number(const json& value, const Where& where) {
    if (!value.is_number()) where.fail("must be a number");
    const double x = value.get<double>();
    if (!std::isfinite(x)) where.fail("must be finite");
    return x;
}

Eigen::Vector3d vector3(const json& value, const Where& where) {
    if (!value.is_array() || value.size() != 3) where.fail("must be an array of 3 numbers");
    return {number(value[0], where.at(0)), number(value[1], where.at(1)),
            number(value[2], where.at(2))};
}

MoverKind kind_from(const json& value, const Where& where) {
    if (value.is_string()) {
        const std::string name = value.get<std::string>();
        for (MoverKind kind : {MoverKind::kCar, MoverKind::kCyclist, MoverKind::kPedestrian}) {
            if (name == to_string(kind)) return kind;
        }
    }
    where.fail("must be \"car\", \"cyclist\" or \"pedestrian\"");
}

MoverTrack track_from(const json& value, const Where& where) {
    MoverTrack track;
    track.kind = kind_from(member(value, "kind", where), where.at("kind"));
    track.size_m = vector3(member(value, "size_m", where), where.at("size_m"));
    if (!(track.size_m.minCoeff() > 0.0)) where.at("size_m").fail("must be positive");
    const json& points = member(value, "waypoints", where);
    const Where points_where = where.at("waypoints");
    if (!points.is_array() || points.empty()) points_where.fail("must be a non-empty array");
    for (std::size_t i = 0; i < points.size(); ++i) {
        const Where w = points_where.at(i);
        MoverWaypoint p;
        p.time_s = number(member(points[i], "t_s", w), w.at("t_s"));
        p.position_m = vector3(member(points[i], "position_m", w), w.at("position_m"));
        p.yaw_rad = number(member(points[i], "yaw_rad", w), w.at("yaw_rad"));
        if (i > 0 && !(p.time_s > track.waypoints.back().time_s)) {
            w.at("t_s").fail("must be later than the previous waypoint's");
        }
        track.waypoints.push_back(p);
    }
    return track;
}

/// The shortest of 15 or 17 significant digits that reads back as `value` (0.1, not
/// 0.10000000000000001).
std::string exact(double value) {
    char buffer[64];
    std::snprintf(buffer, sizeof(buffer), "%.15g", value);
    if (std::strtod(buffer, nullptr) != value) {
        std::snprintf(buffer, sizeof(buffer), "%.17g", value);
    }
    return buffer;
}

std::string exact3(const Eigen::Vector3d& v) {
    return "[" + exact(v.x()) + ", " + exact(v.y()) + ", " + exact(v.z()) + "]";
}

}  // namespace mover_tracks_internal

using namespace mover_tracks_internal;

std::string to_string(MoverKind kind) {
    switch (kind) {
        case MoverKind::kCar:
            return "car";
        case MoverKind::kCyclist:
            return "cyclist";
        case MoverKind::kPedestrian:
            return "pedestrian";
    }
    return "unknown";
}

Eigen::Isometry3d MoverTrack::T_world_body(double time_s) const {
    MoverWaypoint pose = waypoints.empty() ? MoverWaypoint{} : waypoints.front();
    if (waypoints.size() > 1 && time_s > waypoints.front().time_s) {
        const auto next =
            std::upper_bound(waypoints.begin(), waypoints.end(), time_s,
                             [](double t, const MoverWaypoint& p) { return t < p.time_s; });
        if (next == waypoints.end()) {
            pose = waypoints.back();
        } else {
            const MoverWaypoint& a = *(next - 1);
            const MoverWaypoint& b = *next;
            const double s = (time_s - a.time_s) / (b.time_s - a.time_s);
            pose.position_m = a.position_m + s * (b.position_m - a.position_m);
            pose.yaw_rad = a.yaw_rad + s * (b.yaw_rad - a.yaw_rad);
        }
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = pose.position_m;
    T.linear() = Eigen::AngleAxisd(pose.yaw_rad, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    return T;
}

bool MoverTrack::present(double time_s) const {
    return !waypoints.empty() && time_s >= waypoints.front().time_s &&
           time_s <= waypoints.back().time_s;
}

Eigen::AlignedBox3d MoverTrack::box_body() const {
    return {Eigen::Vector3d(-0.5 * size_m.x(), -0.5 * size_m.y(), 0.0),
            Eigen::Vector3d(0.5 * size_m.x(), 0.5 * size_m.y(), size_m.z())};
}

MoverTracks parse_mover_tracks(std::string_view json_text, const std::filesystem::path& source) {
    json root;
    try {
        root = json::parse(json_text.begin(), json_text.end());
    } catch (const json::exception& e) {
        throw DataError("mover tracks '" + source.string() + "': not valid JSON (" + e.what() +
                        ")");
    }
    const Where top{source, "simulation.json"};
    if (!root.is_object() || !root.contains("movers")) {
        throw DataError("mover tracks '" + source.string() +
                        "': no \"movers\" key; the sequence was simulated without movers "
                        "(simulate it with `shine simulate --movers N`)");
    }
    const json& movers = root["movers"];
    const Where where = top.at("movers");
    MoverTracks tracks;
    tracks.frame_period_s =
        number(member(movers, "frame_period_s", where), where.at("frame_period_s"));
    if (!(tracks.frame_period_s > 0.0)) where.at("frame_period_s").fail("must be positive");
    tracks.sweep_s = number(member(movers, "sweep_s", where), where.at("sweep_s"));
    if (!(tracks.sweep_s >= 0.0)) where.at("sweep_s").fail("must be >= 0");
    const json& frames = member(movers, "num_frames", where);
    if (!frames.is_number_integer() || frames.get<long long>() < 0 ||
        frames.get<long long>() > 100000000) {
        where.at("num_frames").fail("must be an integer in [0, 1e8]");
    }
    tracks.num_frames = static_cast<int>(frames.get<long long>());
    const json& list = member(movers, "list", where);
    if (!list.is_array()) where.at("list").fail("must be an array");
    for (std::size_t i = 0; i < list.size(); ++i) {
        tracks.movers.push_back(track_from(list[i], where.at("list").at(i)));
    }
    return tracks;
}

MoverTracks read_mover_tracks(const std::filesystem::path& path) {
    return parse_mover_tracks(read_file_contents(path, "mover tracks", "a simulation.json file"),
                              path);
}

std::string mover_tracks_to_json(const MoverTracks& tracks) {
    std::ostringstream out;
    out << "{\"frame_period_s\": " << exact(tracks.frame_period_s)
        << ", \"sweep_s\": " << exact(tracks.sweep_s) << ", \"num_frames\": " << tracks.num_frames
        << ",\n    \"scan_time\": \"scan k starts at k * frame_period_s; the ray at azimuth step j "
           "of n at k * frame_period_s + sweep_s * j / n\",\n    \"box\": \"[-l/2, l/2] x "
           "[-w/2, w/2] x [0, h] in the body frame (size_m = l, w, h), pose = "
           "translation(position_m) * rotation_z(yaw_rad), linear between waypoints\",\n"
        << "    \"list\": [";
    for (std::size_t i = 0; i < tracks.movers.size(); ++i) {
        const MoverTrack& m = tracks.movers[i];
        out << (i ? ",\n      " : "\n      ") << "{\"kind\": \"" << to_string(m.kind)
            << "\", \"size_m\": " << exact3(m.size_m) << ", \"waypoints\": [";
        for (std::size_t k = 0; k < m.waypoints.size(); ++k) {
            const MoverWaypoint& p = m.waypoints[k];
            out << (k ? ", " : "") << "{\"t_s\": " << exact(p.time_s)
                << ", \"position_m\": " << exact3(p.position_m)
                << ", \"yaw_rad\": " << exact(p.yaw_rad) << "}";
        }
        out << "]}";
    }
    out << "]}";
    return out.str();
}

}  // namespace shine
