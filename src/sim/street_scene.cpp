#include "shine/sim/street_scene.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include "shine/core/error.hpp"
#include "shine/sim/mesh_primitives.hpp"
#include "sim_random.hpp"

namespace shine::sim {
namespace street_internal {

using random_internal::derive_seed;
using random_internal::Rng;

constexpr double kDegToRad = M_PI / 180.0;
constexpr float kSink_m = 0.08f;  ///< objects reach this far below the surface they stand on

/// Independent random streams, so that e.g. more pedestrians do not move the buildings.
enum Stream : std::uint64_t { kBuildings = 1, kCars, kTrees, kPoles, kPedestrians };

struct PendingPart {
    ScenePart info;
    TriangleMesh mesh;
    bool needs_refinement = true;
};

/// Collects the coarse parts of the scene; objects are numbered in creation order.
class SceneAssembler {
  public:
    std::size_t begin_object() { return next_object_++; }
    void add(SceneObjectKind kind, ScenePartSurface surface, std::size_t object, TriangleMesh mesh,
             bool closed = true, bool needs_refinement = true) {
        PendingPart part;
        part.info.kind = kind;
        part.info.surface = surface;
        part.info.object_index = object;
        part.info.closed = closed;
        part.mesh = std::move(mesh);
        part.needs_refinement = needs_refinement;
        parts_.push_back(std::move(part));
    }
    std::vector<PendingPart>& parts() { return parts_; }

  private:
    std::size_t next_object_ = 0;
    std::vector<PendingPart> parts_;
};

/// A disc on a sidewalk that later objects keep clear of.
struct Disc {
    double x, y, radius;
};

bool overlaps(const std::vector<Disc>& discs, double x, double y, double radius) {
    for (const auto& d : discs) {
        if (std::hypot(d.x - x, d.y - y) < d.radius + radius) return true;
    }
    return false;
}

bool inside_polygon(const std::vector<Eigen::Vector2f>& polygon, float x, float y) {
    bool inside = false;
    for (std::size_t i = 0, j = polygon.size() - 1; i < polygon.size(); j = i++) {
        const auto& a = polygon[i];
        const auto& b = polygon[j];
        if ((a.y() > y) != (b.y() > y) &&
            x < (b.x() - a.x()) * (y - a.y()) / (b.y() - a.y()) + a.x()) {
            inside = !inside;
        }
    }
    return inside;
}

void make_counter_clockwise(std::vector<Eigen::Vector2f>& polygon) {
    float area2 = 0.0f;
    for (std::size_t i = 0; i < polygon.size(); ++i) {
        const auto& p = polygon[i];
        const auto& q = polygon[(i + 1) % polygon.size()];
        area2 += p.x() * q.y() - q.x() * p.y();
    }
    if (area2 < 0.0f) std::reverse(polygon.begin(), polygon.end());
}

Eigen::Affine3f yaw_then_translate(double yaw_rad, const Eigen::Vector3d& translation_m) {
    Eigen::Affine3f T = Eigen::Affine3f::Identity();
    T.translate(translation_m.cast<float>());
    T.rotate(Eigen::AngleAxisf(static_cast<float>(yaw_rad), Eigen::Vector3f::UnitZ()));
    return T;
}

/// An axis-aligned box tessellated on a grid (see make_grid_prism_mesh).
TriangleMesh make_grid_box_mesh(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi,
                                float max_edge_m) {
    return make_grid_prism_mesh(
        {{lo.x(), lo.y()}, {hi.x(), lo.y()}, {hi.x(), hi.y()}, {lo.x(), hi.y()}}, lo.z(), hi.z(),
        max_edge_m);
}

/// Street cross-section (y, z) at the building side `side` (+1: y > 0, -1: y < 0).
struct Layout {
    double x0, x1;          ///< street extent along x
    double half_road;       ///< road edge |y|
    double sidewalk_outer;  ///< sidewalk outer edge |y|
    double lot_outer;       ///< ground outer edge |y|
    double sidewalk_z;      ///< curb height
};

/// Buildings along one side; returns their ground footprints (world x-y).
std::vector<std::vector<Eigen::Vector2f>> add_buildings(const StreetSceneConfig& config,
                                                        const Layout& layout, int side, Rng& rng,
                                                        SceneAssembler& scene) {
    std::vector<std::vector<Eigen::Vector2f>> footprints;
    const float base_z = static_cast<float>(layout.sidewalk_z) - kSink_m;
    const auto max_edge = static_cast<float>(config.max_edge_length_m);
    double x = layout.x0 + rng.uniform(0.0, 3.0);
    for (;;) {
        double width = rng.uniform(8.0, 22.0);
        if (x + width > layout.x1 - 0.5) width = layout.x1 - 0.5 - x;
        if (width < 6.0) break;
        const double max_setback =
            std::min(config.building_setback_max_m, config.lot_depth_m - 8.5);
        const double setback = rng.uniform(0.0, max_setback);
        const double depth = rng.uniform(8.0, std::min(14.0, config.lot_depth_m - setback - 0.5));
        const double height =
            rng.uniform(config.building_height_min_m, config.building_height_max_m);
        const double y_front = layout.sidewalk_outer + setback;
        // Local building coordinates: u along the street from x, v away from the street.
        auto to_world = [&](double u, double v) {
            return Eigen::Vector2f(static_cast<float>(x + u),
                                   static_cast<float>(side * (y_front + v)));
        };
        auto polygon_to_world = [&](const std::vector<Eigen::Vector2d>& local) {
            std::vector<Eigen::Vector2f> world;
            for (const auto& p : local) world.push_back(to_world(p.x(), p.y()));
            make_counter_clockwise(world);
            return world;
        };
        auto add_prism = [&](std::size_t object, const std::vector<Eigen::Vector2f>& footprint,
                             double z0, double z1) {
            scene.add(SceneObjectKind::kBuilding, ScenePartSurface::kBuildingBlock, object,
                      make_grid_prism_mesh(footprint, static_cast<float>(z0),
                                           static_cast<float>(z1), max_edge));
        };
        const std::size_t object = scene.begin_object();
        const double w = width, d = depth;
        // The roof part that roof boxes may stand on: local polygon and its top height.
        std::vector<Eigen::Vector2d> top_local = {{0, 0}, {w, 0}, {w, d}, {0, d}};
        double top_z = base_z + height;
        const double shape = rng.uniform(0.0, 1.0);
        if (shape < 0.25) {
            // L-shape: a rectangle with one corner notched out (mirrored to any corner).
            const double wn = rng.uniform(0.3, 0.6) * w;
            const double dn = rng.uniform(0.3, 0.6) * d;
            const bool mirror_u = rng.chance(0.5);
            const bool mirror_v = rng.chance(0.5);
            std::vector<Eigen::Vector2d> l_shape = {{0, 0},           {w, 0},      {w, d - dn},
                                                    {w - wn, d - dn}, {w - wn, d}, {0, d}};
            for (auto& p : l_shape) {
                if (mirror_u) p.x() = w - p.x();
                if (mirror_v) p.y() = d - p.y();
            }
            top_local = l_shape;
            footprints.push_back(polygon_to_world(l_shape));
            add_prism(object, footprints.back(), base_z, top_z);
        } else if (shape < 0.5 && height > 9.0) {
            // Setback: a tower on a podium, stepped back from the street.
            const double podium_height = rng.uniform(0.35, 0.6) * height;
            const std::vector<Eigen::Vector2d> podium = {{0, 0}, {w, 0}, {w, d}, {0, d}};
            footprints.push_back(polygon_to_world(podium));
            add_prism(object, footprints.back(), base_z, base_z + podium_height);
            const double front = rng.uniform(1.5, std::min(4.0, 0.4 * d));
            const double back = rng.uniform(0.0, 1.5);
            const double left = rng.uniform(0.0, std::min(2.5, 0.2 * w));
            const double right = rng.uniform(0.0, std::min(2.5, 0.2 * w));
            top_local = {
                {left, front}, {w - right, front}, {w - right, d - back}, {left, d - back}};
            add_prism(object, polygon_to_world(top_local), base_z + podium_height - kSink_m, top_z);
        } else {
            const std::vector<Eigen::Vector2d> box = {{0, 0}, {w, 0}, {w, d}, {0, d}};
            footprints.push_back(polygon_to_world(box));
            add_prism(object, footprints.back(), base_z, top_z);
            if (height < 12.0 && rng.chance(0.5)) {
                // Gable roof: a triangular prism across the depth, ridge along the street.
                const double ridge = rng.uniform(1.5, 3.0);
                const std::vector<Eigen::Vector2f> profile = {
                    {0.0f, 0.0f},
                    {static_cast<float>(d), 0.0f},
                    {static_cast<float>(d / 2), static_cast<float>(ridge)}};
                TriangleMesh roof = make_prism_mesh(profile, static_cast<float>(w));
                Eigen::Affine3f T = Eigen::Affine3f::Identity();
                // local x -> across the street (away from it), local y -> up, local z -> along x.
                T.linear() << 0, 0, 1, static_cast<float>(side), 0, 0, 0, 1, 0;
                T.translation() =
                    Eigen::Vector3f(static_cast<float>(x), static_cast<float>(side * y_front),
                                    static_cast<float>(top_z) - kSink_m);
                transform_mesh(roof, T);
                scene.add(SceneObjectKind::kBuilding, ScenePartSurface::kGableRoof, object,
                          std::move(roof));
                top_local.clear();  // no roof boxes on a gable roof
            }
        }
        // Roof features: plant rooms, vents, stair houses.
        if (!top_local.empty() && rng.chance(0.6)) {
            const int n = rng.uniform_int(1, 3);
            std::vector<Eigen::Vector2f> top_world;
            for (const auto& p : top_local) top_world.push_back(to_world(p.x(), p.y()));
            for (int k = 0; k < n; ++k) {
                const double su = rng.uniform(1.0, 3.5), sv = rng.uniform(1.0, 3.5);
                const double sz = rng.uniform(0.8, 3.0);
                const double u = rng.uniform(0.5, std::max(0.6, w - su - 0.5));
                const double v = rng.uniform(0.5, std::max(0.6, d - sv - 0.5));
                const Eigen::Vector2f a = to_world(u, v), b = to_world(u + su, v + sv);
                bool fits = true;
                for (const auto& corner : {to_world(u, v), to_world(u + su, v), to_world(u, v + sv),
                                           to_world(u + su, v + sv)}) {
                    fits = fits && inside_polygon(top_world, corner.x(), corner.y());
                }
                if (!fits) continue;
                scene.add(SceneObjectKind::kBuilding, ScenePartSurface::kRoofBox, object,
                          make_grid_box_mesh({std::min(a.x(), b.x()), std::min(a.y(), b.y()),
                                              static_cast<float>(top_z) - kSink_m},
                                             {std::max(a.x(), b.x()), std::max(a.y(), b.y()),
                                              static_cast<float>(top_z + sz)},
                                             max_edge));
            }
        }
        x += width + rng.uniform(config.building_gap_min_m, config.building_gap_max_m);
    }
    return footprints;
}

/// A parked car (sedan or van): a side-profile prism plus four wheels.
void add_car(double center_x, double center_y, double yaw_rad, float max_edge, Rng& rng,
             SceneAssembler& scene) {
    const bool van = rng.chance(0.2);
    const double length = van ? rng.uniform(4.6, 5.4) : rng.uniform(3.8, 4.8);
    const double width = van ? rng.uniform(1.85, 2.05) : rng.uniform(1.65, 1.9);
    const double height = van ? rng.uniform(1.9, 2.3) : rng.uniform(1.35, 1.6);
    const double clearance = 0.28;
    const double L = length, H = height;
    std::vector<Eigen::Vector2d> profile;  // (along the car from the rear, up)
    if (van) {
        profile = {{0, clearance},       {L, clearance}, {L, 0.5 * H},
                   {L - 0.35, 0.62 * H}, {L - 1.0, H},   {0, H}};
    } else {
        const double belt = 0.62 * H;
        profile = {{0, clearance},  {L, clearance},          {L, belt - 0.12},
                   {L - 0.2, belt}, {0.7 * L, belt + 0.03},  {0.58 * L, H},
                   {0.22 * L, H},   {0.08 * L, belt + 0.05}, {0, belt - 0.05}};
    }
    std::vector<Eigen::Vector2f> profile_f;
    for (const auto& p : profile) profile_f.emplace_back(p.cast<float>());
    TriangleMesh body = make_prism_mesh(profile_f, static_cast<float>(width));
    // Prism frame -> car frame (x forward, y left, z up, origin at the centre of the ground
    // contact): local x -> x, local y -> z, local z -> -y.
    Eigen::Affine3f T_car_prism = Eigen::Affine3f::Identity();
    T_car_prism.linear() << 1, 0, 0, 0, 0, -1, 0, 1, 0;
    T_car_prism.translation() =
        Eigen::Vector3f(static_cast<float>(-L / 2), static_cast<float>(width / 2), 0.0f);
    const Eigen::Affine3f T_world_car =
        yaw_then_translate(yaw_rad, Eigen::Vector3d(center_x, center_y, 0.0));
    transform_mesh(body, T_world_car * T_car_prism);
    const std::size_t object = scene.begin_object();
    scene.add(SceneObjectKind::kCar, ScenePartSurface::kCarBody, object, std::move(body));
    const float radius = static_cast<float>(van ? 0.36 : 0.32);
    const float wheel_width = 0.22f;
    for (const double wx : {-L / 2 + 0.85, L / 2 - 0.85}) {
        for (const double y_inner : {width / 2 - 0.03 - wheel_width, -width / 2 + 0.03}) {
            TriangleMesh wheel = make_grid_cylinder_mesh(radius, wheel_width, max_edge);
            // Cylinder axis (local z) -> car y.
            Eigen::Affine3f T_car_wheel = Eigen::Affine3f::Identity();
            T_car_wheel.linear() << 1, 0, 0, 0, 0, 1, 0, 1, 0;
            T_car_wheel.translation() = Eigen::Vector3f(
                static_cast<float>(wx), static_cast<float>(y_inner), radius - 0.02f);
            transform_mesh(wheel, T_world_car * T_car_wheel);
            scene.add(SceneObjectKind::kCar, ScenePartSurface::kCarWheel, object, std::move(wheel));
        }
    }
}

void add_tree(double x, double y, double ground_z, double trunk_radius, float max_edge, Rng& rng,
              SceneAssembler& scene) {
    const std::size_t object = scene.begin_object();
    const double trunk_height = rng.uniform(2.0, 3.5);
    TriangleMesh trunk = make_grid_cylinder_mesh(
        static_cast<float>(trunk_radius), static_cast<float>(trunk_height + kSink_m), max_edge);
    transform_mesh(trunk, yaw_then_translate(0.0, Eigen::Vector3d(x, y, ground_z - kSink_m)));
    scene.add(SceneObjectKind::kTree, ScenePartSurface::kTreeTrunk, object, std::move(trunk));
    const double radius_xy = rng.uniform(1.2, 2.4);
    const double radius_z = rng.uniform(1.2, 2.6);
    TriangleMesh crown =
        make_ellipsoid_mesh(Eigen::Vector3f(static_cast<float>(radius_xy),
                                            static_cast<float>(radius_xy * rng.uniform(0.8, 1.2)),
                                            static_cast<float>(radius_z)),
                            2);
    // The crown swallows the top of the trunk.
    transform_mesh(
        crown, yaw_then_translate(rng.uniform(0.0, M_PI),
                                  Eigen::Vector3d(x, y, ground_z + trunk_height + 0.6 * radius_z)));
    scene.add(SceneObjectKind::kTree, ScenePartSurface::kTreeCrown, object, std::move(crown));
}

void add_pole(double x, double y, double ground_z, int side, double radius, float max_edge,
              Rng& rng, SceneAssembler& scene) {
    const std::size_t object = scene.begin_object();
    const double height = rng.uniform(4.0, 8.0);
    TriangleMesh pole = make_grid_cylinder_mesh(static_cast<float>(radius),
                                                static_cast<float>(height + kSink_m), max_edge);
    transform_mesh(pole, yaw_then_translate(0.0, Eigen::Vector3d(x, y, ground_z - kSink_m)));
    scene.add(SceneObjectKind::kPole, ScenePartSurface::kPoleMast, object, std::move(pole));
    if (rng.chance(0.5)) {
        // Street lamp: an arm reaching over the road and a lamp head.
        const double top = ground_z + height;
        const double arm = rng.uniform(1.2, 2.0);
        const double y_end = y - side * arm;
        const auto lo = [](double a, double b) { return static_cast<float>(std::min(a, b)); };
        const auto hi = [](double a, double b) { return static_cast<float>(std::max(a, b)); };
        scene.add(SceneObjectKind::kPole, ScenePartSurface::kLampArm, object,
                  make_grid_box_mesh(
                      {static_cast<float>(x - 0.05), lo(y, y_end), static_cast<float>(top - 0.32)},
                      {static_cast<float>(x + 0.05), hi(y, y_end), static_cast<float>(top - 0.2)},
                      max_edge));
        const double head_y0 = y_end, head_y1 = y_end + side * 0.55;
        scene.add(SceneObjectKind::kPole, ScenePartSurface::kLampHead, object,
                  make_grid_box_mesh({static_cast<float>(x - 0.14), lo(head_y0, head_y1),
                                      static_cast<float>(top - 0.45)},
                                     {static_cast<float>(x + 0.14), hi(head_y0, head_y1),
                                      static_cast<float>(top - 0.26)},
                                     max_edge));
    }
}

void add_pedestrian(double x, double y, double ground_z, float max_edge, Rng& rng,
                    SceneAssembler& scene) {
    const std::size_t object = scene.begin_object();
    const float s = static_cast<float>(rng.uniform(0.92, 1.08));  // 1.56 .. 1.84 m tall
    const Eigen::Affine3f T =
        yaw_then_translate(rng.uniform(0.0, 2.0 * M_PI), Eigen::Vector3d(x, y, ground_z - 0.02));
    TriangleMesh legs = make_grid_box_mesh(s * Eigen::Vector3f(-0.1f, -0.16f, 0.0f),
                                           s * Eigen::Vector3f(0.1f, 0.16f, 0.86f), max_edge);
    TriangleMesh torso = make_grid_box_mesh(s * Eigen::Vector3f(-0.13f, -0.21f, 0.82f),
                                            s * Eigen::Vector3f(0.13f, 0.21f, 1.46f), max_edge);
    TriangleMesh head = make_ellipsoid_mesh(s * Eigen::Vector3f(0.1f, 0.09f, 0.13f), 1);
    for (auto& v : head.vertices) v.z() += s * 1.59f;  // top of the head at s * 1.72 m
    const std::pair<TriangleMesh*, ScenePartSurface> parts[] = {
        {&legs, ScenePartSurface::kPedestrianLegs},
        {&torso, ScenePartSurface::kPedestrianTorso},
        {&head, ScenePartSurface::kPedestrianHead}};
    for (const auto& [part, surface] : parts) {
        transform_mesh(*part, T);
        scene.add(SceneObjectKind::kPedestrian, surface, object, std::move(*part));
    }
}

/// The ground: road, curbs and sidewalks/lots as one open grid surface whose cells have a
/// diagonal of at most max_edge; cells fully inside a building footprint are left out (the
/// building's closed bottom lies there).
TriangleMesh make_ground(const Layout& layout, double max_edge_m,
                         const std::vector<std::vector<Eigen::Vector2f>>& footprints) {
    const double step = 0.999 * max_edge_m / std::sqrt(2.0);
    const double sz = layout.sidewalk_z;
    // Cross-section polyline (y, z) from -y to +y; normals: x cross (profile direction).
    const std::vector<Eigen::Vector2d> corners = {{-layout.lot_outer, sz},  {-layout.half_road, sz},
                                                  {-layout.half_road, 0.0}, {layout.half_road, 0.0},
                                                  {layout.half_road, sz},   {layout.lot_outer, sz}};
    std::vector<Eigen::Vector2d> profile = {corners[0]};
    for (std::size_t k = 0; k + 1 < corners.size(); ++k) {
        const int n =
            std::max(1, static_cast<int>(std::ceil((corners[k + 1] - corners[k]).norm() / step)));
        for (int i = 1; i <= n; ++i) {
            profile.push_back(corners[k] +
                              (corners[k + 1] - corners[k]) * (static_cast<double>(i) / n));
        }
    }
    const int nx = std::max(1, static_cast<int>(std::ceil((layout.x1 - layout.x0) / step)));
    const int np = static_cast<int>(profile.size());
    TriangleMesh mesh;
    mesh.vertices.reserve(static_cast<std::size_t>(nx + 1) * np);
    for (int i = 0; i <= nx; ++i) {
        const double x = layout.x0 + (layout.x1 - layout.x0) * (static_cast<double>(i) / nx);
        for (const auto& p : profile) {
            mesh.vertices.emplace_back(static_cast<float>(x), static_cast<float>(p.x()),
                                       static_cast<float>(p.y()));
        }
    }
    // Footprint bounding boxes for a quick reject.
    std::vector<Eigen::AlignedBox2f> boxes;
    for (const auto& f : footprints) {
        Eigen::AlignedBox2f box;
        for (const auto& p : f) box.extend(p);
        boxes.push_back(box);
    }
    auto inside_some_building = [&](const std::array<Eigen::Vector2f, 4>& cell) {
        for (std::size_t b = 0; b < footprints.size(); ++b) {
            bool all = true;
            for (const auto& c : cell) {
                all = all && boxes[b].contains(c) && inside_polygon(footprints[b], c.x(), c.y());
            }
            if (all) return true;
        }
        return false;
    };
    auto index = [np](int i, int k) { return i * np + k; };
    for (int i = 0; i < nx; ++i) {
        for (int k = 0; k + 1 < np; ++k) {
            const int a = index(i, k), b = index(i + 1, k), c = index(i + 1, k + 1),
                      d = index(i, k + 1);
            const std::array<Eigen::Vector2f, 4> cell = {
                mesh.vertices[a].head<2>(), mesh.vertices[b].head<2>(), mesh.vertices[c].head<2>(),
                mesh.vertices[d].head<2>()};
            if (std::abs(profile[k].x()) > layout.sidewalk_outer && inside_some_building(cell)) {
                continue;
            }
            mesh.triangles.emplace_back(a, b, c);
            mesh.triangles.emplace_back(a, c, d);
        }
    }
    // Drop vertices that only belonged to removed cells.
    std::vector<int> remap(mesh.vertices.size(), -1);
    std::vector<Eigen::Vector3f> used;
    for (auto& t : mesh.triangles) {
        for (int j = 0; j < 3; ++j) {
            if (remap[t[j]] < 0) {
                remap[t[j]] = static_cast<int>(used.size());
                used.push_back(mesh.vertices[t[j]]);
            }
            t[j] = remap[t[j]];
        }
    }
    mesh.vertices = std::move(used);
    return mesh;
}

}  // namespace street_internal

using namespace street_internal;

std::string to_string(SceneObjectKind kind) {
    switch (kind) {
        case SceneObjectKind::kGround:
            return "ground";
        case SceneObjectKind::kBuilding:
            return "building";
        case SceneObjectKind::kTree:
            return "tree";
        case SceneObjectKind::kCar:
            return "car";
        case SceneObjectKind::kPole:
            return "pole";
        case SceneObjectKind::kPedestrian:
            return "pedestrian";
    }
    return "unknown";
}

std::string to_string(ScenePartSurface surface) {
    switch (surface) {
        case ScenePartSurface::kGround:
            return "ground";
        case ScenePartSurface::kBuildingBlock:
            return "building block";
        case ScenePartSurface::kGableRoof:
            return "gable roof";
        case ScenePartSurface::kRoofBox:
            return "roof box";
        case ScenePartSurface::kCarBody:
            return "car body";
        case ScenePartSurface::kCarWheel:
            return "car wheel";
        case ScenePartSurface::kTreeTrunk:
            return "tree trunk";
        case ScenePartSurface::kTreeCrown:
            return "tree crown";
        case ScenePartSurface::kPoleMast:
            return "pole mast";
        case ScenePartSurface::kLampArm:
            return "lamp arm";
        case ScenePartSurface::kLampHead:
            return "lamp head";
        case ScenePartSurface::kPedestrianLegs:
            return "pedestrian legs";
        case ScenePartSurface::kPedestrianTorso:
            return "pedestrian torso";
        case ScenePartSurface::kPedestrianHead:
            return "pedestrian head";
    }
    return "unknown";
}

std::size_t StreetScene::count_objects(SceneObjectKind kind) const {
    std::set<std::size_t> objects;
    for (const auto& part : parts) {
        if (part.kind == kind) objects.insert(part.object_index);
    }
    return objects.size();
}

void validate(const StreetSceneConfig& c) {
    auto require = [](bool ok, const std::string& key, double value, const std::string& rule) {
        if (!ok) {
            throw ConfigError("street scene: " + key + " = " + std::to_string(value) + " " + rule);
        }
    };
    require(std::isfinite(c.start_x_m), "start_x_m", c.start_x_m, "must be finite");
    require(c.length_m >= 20.0 && c.length_m <= 1e5, "length_m", c.length_m,
            "must be in [20, 100000]");
    require(c.road_width_m >= 4.0, "road_width_m", c.road_width_m, "must be >= 4");
    require(c.sidewalk_width_m >= 1.5, "sidewalk_width_m", c.sidewalk_width_m, "must be >= 1.5");
    require(c.curb_height_m > 0.0 && c.curb_height_m <= 0.5, "curb_height_m", c.curb_height_m,
            "must be in (0, 0.5]");
    require(c.lot_depth_m >= 10.0, "lot_depth_m", c.lot_depth_m,
            "must be >= 10 (buildings are at least 8 m deep)");
    require(c.building_height_min_m >= 2.0, "building_height_min_m", c.building_height_min_m,
            "must be >= 2");
    require(c.building_height_max_m >= c.building_height_min_m, "building_height_max_m",
            c.building_height_max_m, "must be >= building_height_min_m");
    require(c.building_setback_max_m >= 0.0 && c.building_setback_max_m <= 100.0,
            "building_setback_max_m", c.building_setback_max_m, "must be in [0, 100]");
    require(c.building_gap_min_m > 0.0, "building_gap_min_m", c.building_gap_min_m, "must be > 0");
    require(c.building_gap_max_m >= c.building_gap_min_m, "building_gap_max_m",
            c.building_gap_max_m, "must be >= building_gap_min_m");
    require(c.tree_spacing_m >= 3.0, "tree_spacing_m", c.tree_spacing_m, "must be >= 3");
    require(c.pole_spacing_m >= 3.0, "pole_spacing_m", c.pole_spacing_m, "must be >= 3");
    require(c.car_spacing_m >= 6.0, "car_spacing_m", c.car_spacing_m, "must be >= 6");
    require(c.pedestrians_per_100m >= 0.0 && c.pedestrians_per_100m <= 200.0,
            "pedestrians_per_100m", c.pedestrians_per_100m, "must be in [0, 200]");
    require(c.max_edge_length_m >= 0.02 && c.max_edge_length_m <= 10.0, "max_edge_length_m",
            c.max_edge_length_m, "must be in [0.02, 10]");
}

StreetScene make_street_scene(const StreetSceneConfig& config) {
    validate(config);
    Layout layout;
    layout.x0 = config.start_x_m;
    layout.x1 = config.start_x_m + config.length_m;
    layout.half_road = config.road_width_m / 2;
    layout.sidewalk_outer = layout.half_road + config.sidewalk_width_m;
    layout.lot_outer = layout.sidewalk_outer + config.lot_depth_m;
    layout.sidewalk_z = config.curb_height_m;

    SceneAssembler scene;
    const std::size_t ground_object = scene.begin_object();
    std::vector<std::vector<Eigen::Vector2f>> footprints;
    {
        Rng rng(derive_seed(config.seed, kBuildings));
        for (const int side : {-1, 1}) {
            auto side_footprints = add_buildings(config, layout, side, rng, scene);
            footprints.insert(footprints.end(), side_footprints.begin(), side_footprints.end());
        }
    }
    {
        Rng rng(derive_seed(config.seed, kCars));
        const double mean_length = 4.5;
        for (const int side : {-1, 1}) {
            double x = layout.x0 + rng.uniform(0.0, 5.0);
            for (;;) {
                const double gap = rng.uniform(
                    0.8, std::max(1.0, 2.0 * (config.car_spacing_m - mean_length) - 0.8));
                x += gap + (rng.chance(0.15) ? rng.uniform(6.0, 15.0) : 0.0);
                const double center_x = x + mean_length / 2 + 0.5;
                if (center_x + 3.5 > layout.x1) break;
                // Right-hand traffic: cars at y < 0 face +x, cars at y > 0 face -x.
                const double yaw = (side < 0 ? 0.0 : M_PI) + rng.uniform(-2.0, 2.0) * kDegToRad;
                const double center_y = side * (layout.half_road - 0.35 - 1.0);
                add_car(center_x, center_y, yaw, static_cast<float>(config.max_edge_length_m), rng,
                        scene);
                x += mean_length + 1.0;
            }
        }
    }
    std::vector<Disc> occupied;
    {
        Rng rng(derive_seed(config.seed, kTrees));
        for (const int side : {-1, 1}) {
            double x = layout.x0 + rng.uniform(1.0, config.tree_spacing_m);
            while (x < layout.x1 - 3.0) {
                const double y =
                    side * (layout.half_road + config.sidewalk_width_m * rng.uniform(0.55, 0.8));
                const double trunk_radius = rng.uniform(0.12, 0.25);
                add_tree(x, y, layout.sidewalk_z, trunk_radius,
                         static_cast<float>(config.max_edge_length_m), rng, scene);
                occupied.push_back({x, y, trunk_radius + 0.4});
                x += config.tree_spacing_m * rng.uniform(0.5, 1.5);
            }
        }
    }
    {
        Rng rng(derive_seed(config.seed, kPoles));
        for (const int side : {-1, 1}) {
            double x = layout.x0 + rng.uniform(1.0, config.pole_spacing_m);
            while (x < layout.x1 - 2.0) {
                const double y = side * (layout.half_road + 0.45);
                const double radius = rng.uniform(0.1, 0.15);
                if (!overlaps(occupied, x, y, radius + 0.3)) {
                    add_pole(x, y, layout.sidewalk_z, side, radius,
                             static_cast<float>(config.max_edge_length_m), rng, scene);
                    occupied.push_back({x, y, radius + 0.3});
                }
                x += config.pole_spacing_m * rng.uniform(0.5, 1.5);
            }
        }
    }
    {
        Rng rng(derive_seed(config.seed, kPedestrians));
        const double mean = config.pedestrians_per_100m * config.length_m / 100.0;
        const int count = static_cast<int>(std::lround(mean * rng.uniform(0.7, 1.3)));
        for (int i = 0; i < count; ++i) {
            for (int attempt = 0; attempt < 20; ++attempt) {
                const int side = rng.chance(0.5) ? 1 : -1;
                const double x = rng.uniform(layout.x0 + 1.0, layout.x1 - 1.0);
                const double y =
                    side * rng.uniform(layout.half_road + 0.7, layout.sidewalk_outer - 0.4);
                if (overlaps(occupied, x, y, 0.35)) continue;
                add_pedestrian(x, y, layout.sidewalk_z,
                               static_cast<float>(config.max_edge_length_m), rng, scene);
                occupied.push_back({x, y, 0.35});
                break;
            }
        }
    }
    scene.add(SceneObjectKind::kGround, ScenePartSurface::kGround, ground_object,
              make_ground(layout, config.max_edge_length_m, footprints), /*closed=*/false,
              /*needs_refinement=*/false);

    // Refine every part on its own (parts share no vertices), in parallel; the result does not
    // depend on the schedule because each part's refinement is deterministic.
    auto& parts = scene.parts();
    const auto max_edge = static_cast<float>(config.max_edge_length_m);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, parts.size(), 1),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              if (parts[i].needs_refinement) {
                                  refine_to_max_edge(parts[i].mesh, max_edge);
                              }
                          }
                      });
    // Ground first, then objects in creation order.
    std::stable_partition(parts.begin(), parts.end(), [](const PendingPart& p) {
        return p.info.kind == SceneObjectKind::kGround;
    });
    StreetScene result;
    std::size_t n_vertices = 0, n_triangles = 0;
    for (const auto& p : parts) {
        n_vertices += p.mesh.vertices.size();
        n_triangles += p.mesh.triangles.size();
    }
    result.mesh.vertices.reserve(n_vertices);
    result.mesh.triangles.reserve(n_triangles);
    for (auto& p : parts) {
        p.info.first_triangle = result.mesh.triangles.size();
        p.info.num_triangles = p.mesh.triangles.size();
        append_mesh(result.mesh, p.mesh);
        result.parts.push_back(p.info);
    }
    return result;
}

}  // namespace shine::sim
