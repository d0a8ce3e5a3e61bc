#include "shine/sim/scene_albedo.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "shine/core/error.hpp"
#include "sim_random.hpp"

namespace shine::sim {
namespace albedo_internal {

using random_internal::splitmix64;

/// Salts, so that e.g. a building's palette entry and its pattern are independent draws.
enum Salt : std::uint64_t {
    kFacadeColour = 1,
    kFacadePattern,
    kGableTileColour,
    kCarColour,
    kCrownGreen,
    kTopColour,
    kSkin,
    kMoverColour
};

/// A well-mixed number for (object, salt).
std::uint64_t object_hash(std::size_t object, Salt salt) {
    return splitmix64(splitmix64(static_cast<std::uint64_t>(object)) ^ (salt * 0x9E3779B1ULL));
}

template <std::size_t N>
Rgb pick(const std::array<Rgb, N>& palette, std::size_t object, Salt salt) {
    return palette[object_hash(object, salt) % N];
}

/// `c` scaled by `factor` (< 1 darker), clamped to [0, 255].
Rgb shade(Rgb c, double factor) {
    auto channel = [factor](std::uint8_t v) {
        return static_cast<std::uint8_t>(std::clamp(std::lround(v * factor), 0L, 255L));
    };
    return {channel(c.r), channel(c.g), channel(c.b)};
}

/// `c` mixed with white by `amount` in [0, 1].
Rgb lighten(Rgb c, double amount) {
    auto channel = [amount](std::uint8_t v) {
        return static_cast<std::uint8_t>(std::lround(v + (255.0 - v) * amount));
    };
    return {channel(c.r), channel(c.g), channel(c.b)};
}

/// x modulo `period`, in [0, period) also for negative x.
double wrap(double x, double period) { return x - period * std::floor(x / period); }

/// Parity of the cell of x in cells of `size`.
bool odd_cell(double x, double size) {
    return (static_cast<long long>(std::floor(x / size)) & 1LL) != 0;
}

constexpr Rgb kAsphalt{62, 62, 66};
constexpr Rgb kMarking{235, 235, 228};
constexpr Rgb kCurbConcrete{165, 163, 158};
constexpr Rgb kPaving{192, 187, 178};
constexpr Rgb kPavingJoint{138, 134, 128};
constexpr Rgb kGrass{104, 136, 72};
constexpr Rgb kGlass{48, 62, 84};
constexpr Rgb kFlatRoof{128, 128, 124};
constexpr Rgb kRoofBox{176, 176, 170};
constexpr Rgb kWheel{28, 28, 30};
constexpr Rgb kBark{96, 70, 48};
constexpr Rgb kMetal{118, 122, 128};
constexpr Rgb kLamp{240, 232, 180};
constexpr Rgb kTrousers{45, 50, 72};
constexpr Rgb kCyclist{240, 120, 0};

constexpr std::array<Rgb, 10> kFacades = {{{196, 92, 72},
                                           {222, 196, 140},
                                           {150, 160, 172},
                                           {110, 140, 100},
                                           {230, 226, 214},
                                           {170, 110, 150},
                                           {96, 122, 168},
                                           {214, 150, 70},
                                           {140, 100, 80},
                                           {90, 160, 160}}};
constexpr std::array<Rgb, 9> kCarColours = {{{200, 30, 35},
                                             {30, 70, 190},
                                             {230, 190, 20},
                                             {30, 150, 60},
                                             {235, 120, 20},
                                             {120, 40, 150},
                                             {20, 170, 190},
                                             {200, 40, 140},
                                             {140, 200, 30}}};
constexpr std::array<Rgb, 5> kGreens = {
    {{40, 100, 40}, {60, 125, 45}, {85, 140, 50}, {35, 85, 55}, {70, 110, 30}}};
constexpr std::array<Rgb, 6> kTops = {
    {{180, 40, 40}, {40, 90, 160}, {220, 200, 60}, {60, 140, 80}, {230, 230, 225}, {150, 80, 160}}};
constexpr std::array<Rgb, 3> kSkins = {{{224, 184, 152}, {180, 130, 95}, {120, 84, 60}}};
constexpr std::array<Rgb, 2> kGableTiles = {{{170, 80, 55}, {82, 88, 98}}};

// Lane markings and paving (metres).
constexpr double kCentreLineHalfWidthM = 0.075;
constexpr double kDashPeriodM = 6.0;
constexpr double kDashLengthM = 3.0;
constexpr double kParkingLaneWidthM = 2.3;  ///< the lane line's distance from the curb
constexpr double kLaneLineHalfWidthM = 0.06;
constexpr double kSlabM = 1.0;
constexpr double kJointM = 0.06;
// Facades (metres).
constexpr double kStoreyM = 3.0;
constexpr double kWindowBottomM = 0.9;  ///< above the storey's floor
constexpr double kWindowTopM = 2.3;
constexpr double kWindowPeriodM = 2.0;
constexpr double kWindowWidthM = 1.2;
constexpr double kBandM = 1.0;
constexpr double kCourseM = 0.5;
/// |normal.z| above this: a roof (or a bottom); below kWallNormalZ: a wall.
constexpr double kRoofNormalZ = 0.7;
constexpr double kWallNormalZ = 0.3;

Rgb ground_albedo(const Eigen::Vector3d& p, const Eigen::Vector3d& n, const StreetCrossSection& s) {
    if (std::abs(n.z()) < kRoofNormalZ) return kCurbConcrete;  // a curb's vertical face
    const double y = std::abs(p.y());
    if (p.z() < 0.5 * s.curb_height_m) {
        const bool centre = y < kCentreLineHalfWidthM && wrap(p.x(), kDashPeriodM) < kDashLengthM;
        const double lane_line_y = s.half_road_m - kParkingLaneWidthM;
        const bool lane_line = lane_line_y > 1.0 && std::abs(y - lane_line_y) < kLaneLineHalfWidthM;
        return centre || lane_line ? kMarking : kAsphalt;
    }
    if (y < s.sidewalk_outer_m) {
        const bool joint =
            wrap(p.x(), kSlabM) < kJointM || wrap(y - s.half_road_m, kSlabM) < kJointM;
        return joint ? kPavingJoint : kPaving;
    }
    return odd_cell(p.x(), 1.0) != odd_cell(p.y(), 1.0) ? shade(kGrass, 0.9) : kGrass;
}

Rgb facade_albedo(const Eigen::Vector3d& p, const Eigen::Vector3d& n, std::size_t object) {
    const Rgb base = pick(kFacades, object, kFacadeColour);
    // Along the wall: the horizontal direction in the wall's plane (walls are vertical).
    const double s = -n.y() * p.x() + n.x() * p.y();
    switch (object_hash(object, kFacadePattern) % 3) {
        case 0: {  // a window grid, one row of windows per storey
            const double in_storey = wrap(p.z(), kStoreyM);
            const double across = wrap(s, kWindowPeriodM);
            const double margin = 0.5 * (kWindowPeriodM - kWindowWidthM);
            if (in_storey >= kWindowBottomM && in_storey < kWindowTopM && across >= margin &&
                across < margin + kWindowWidthM) {
                return kGlass;
            }
            return base;
        }
        case 1:  // horizontal bands
            return odd_cell(p.z(), kBandM) ? lighten(base, 0.35) : base;
        default:  // brick courses
            return odd_cell(p.z(), kCourseM) ? shade(base, 0.78) : base;
    }
}

Rgb building_albedo(const SurfacePoint& q) {
    const Eigen::Vector3d& n = q.normal;
    switch (q.surface) {
        case ScenePartSurface::kBuildingBlock:
            if (n.z() > kRoofNormalZ) return kFlatRoof;
            if (n.z() < -kRoofNormalZ) return pick(kFacades, q.object_index, kFacadeColour);
            return facade_albedo(q.point_m, n, q.object_index);
        case ScenePartSurface::kGableRoof: {
            if (std::abs(n.z()) < kWallNormalZ) {
                return pick(kFacades, q.object_index, kFacadeColour);  // a gable end
            }
            const Rgb tiles = pick(kGableTiles, q.object_index, kGableTileColour);
            return odd_cell(q.point_m.z(), 0.5 * kCourseM) ? shade(tiles, 0.82) : tiles;
        }
        default:  // a roof box
            return n.z() > kRoofNormalZ ? shade(kRoofBox, 0.85) : kRoofBox;
    }
}

}  // namespace albedo_internal

using namespace albedo_internal;

StreetCrossSection cross_section_of(const StreetSceneConfig& config) {
    StreetCrossSection s;
    s.half_road_m = config.road_width_m / 2;
    s.sidewalk_outer_m = s.half_road_m + config.sidewalk_width_m;
    s.curb_height_m = config.curb_height_m;
    return s;
}

Rgb surface_albedo(const SurfacePoint& q, const StreetCrossSection& street) {
    const Eigen::Vector3d& p = q.point_m;
    switch (q.surface) {
        case ScenePartSurface::kGround:
            return ground_albedo(p, q.normal, street);
        case ScenePartSurface::kBuildingBlock:
        case ScenePartSurface::kGableRoof:
        case ScenePartSurface::kRoofBox:
            return building_albedo(q);
        case ScenePartSurface::kCarBody:
            return pick(kCarColours, q.object_index, kCarColour);
        case ScenePartSurface::kCarWheel:
            return kWheel;
        case ScenePartSurface::kTreeTrunk:
            return kBark;
        case ScenePartSurface::kTreeCrown: {
            const Rgb green = pick(kGreens, q.object_index, kCrownGreen);
            const bool odd = (odd_cell(p.x(), 0.5) != odd_cell(p.y(), 0.5)) != odd_cell(p.z(), 0.5);
            return odd ? shade(green, 0.82) : green;
        }
        case ScenePartSurface::kPoleMast:
        case ScenePartSurface::kLampArm:
            return kMetal;
        case ScenePartSurface::kLampHead:
            return kLamp;
        case ScenePartSurface::kPedestrianLegs:
            return kTrousers;
        case ScenePartSurface::kPedestrianTorso:
            return pick(kTops, q.object_index, kTopColour);
        case ScenePartSurface::kPedestrianHead:
            return pick(kSkins, q.object_index, kSkin);
    }
    return kAsphalt;
}

Rgb mover_albedo(MoverKind kind, std::size_t mover_index) {
    switch (kind) {
        case MoverKind::kCar:
            return pick(kCarColours, mover_index, kMoverColour);
        case MoverKind::kCyclist:
            return kCyclist;
        case MoverKind::kPedestrian:
            return pick(kTops, mover_index, kMoverColour);
    }
    return kCyclist;
}

SceneAlbedo::SceneAlbedo(const StreetScene& scene, const StreetSceneConfig& config)
    : scene_(&scene), street_(cross_section_of(config)) {
    std::size_t next = 0;
    for (const ScenePart& part : scene.parts) {
        if (part.first_triangle != next) {
            throw ConfigError(
                "SceneAlbedo: the scene's parts must cover its triangles in order; "
                "a part starts at triangle " +
                std::to_string(part.first_triangle) + " instead of " + std::to_string(next) +
                " (build the scene with make_street_scene)");
        }
        next += part.num_triangles;
    }
    if (next != scene.mesh.triangles.size()) {
        throw ConfigError("SceneAlbedo: the scene's parts cover " + std::to_string(next) + " of " +
                          std::to_string(scene.mesh.triangles.size()) +
                          " triangles (build the scene with make_street_scene)");
    }
}

const ScenePart& SceneAlbedo::part_of(std::int32_t triangle_id) const {
    if (triangle_id < 0 || static_cast<std::size_t>(triangle_id) >= scene_->mesh.triangles.size()) {
        throw ConfigError("SceneAlbedo: triangle " + std::to_string(triangle_id) +
                          " is not in the scene's mesh of " +
                          std::to_string(scene_->mesh.triangles.size()) +
                          " triangles (a miss has no albedo: use kSkyColour)");
    }
    const auto t = static_cast<std::size_t>(triangle_id);
    const auto& parts = scene_->parts;
    const auto after = std::upper_bound(
        parts.begin(), parts.end(), t,
        [](std::size_t id, const ScenePart& part) { return id < part.first_triangle; });
    return *(after - 1);
}

SurfacePoint SceneAlbedo::surface_point(std::int32_t triangle_id,
                                        const Eigen::Vector3d& point_m) const {
    const ScenePart& part = part_of(triangle_id);
    const TriangleMesh& mesh = scene_->mesh;
    const Eigen::Vector3i& t = mesh.triangles[static_cast<std::size_t>(triangle_id)];
    const Eigen::Vector3d a = mesh.vertices[t[0]].cast<double>();
    const Eigen::Vector3d normal =
        (mesh.vertices[t[1]].cast<double>() - a).cross(mesh.vertices[t[2]].cast<double>() - a);
    SurfacePoint q;
    q.surface = part.surface;
    q.object_index = part.object_index;
    q.point_m = point_m;
    const double length = normal.norm();
    q.normal = length > 0.0 ? Eigen::Vector3d(normal / length) : Eigen::Vector3d::UnitZ();
    return q;
}

Rgb SceneAlbedo::at(std::int32_t triangle_id, const Eigen::Vector3d& point_m) const {
    return surface_albedo(surface_point(triangle_id, point_m), street_);
}

}  // namespace shine::sim
