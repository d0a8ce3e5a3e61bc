#include "shine/sim/object_scene.hpp"

#include <cmath>
#include <string>

#include "shine/core/error.hpp"
#include "shine/sim/mesh_primitives.hpp"
#include "sim_random.hpp"

namespace shine::sim {
namespace object_internal {

using random_internal::Rng;

/// Appends `part` placed by `T` (refined to the edge limit) and grows the object's box.
void add_part(ObjectScene& scene, TriangleMesh part, const Eigen::Affine3f& T, float max_edge_m,
              bool is_object) {
    transform_mesh(part, T);
    refine_to_max_edge(part, max_edge_m);
    if (is_object) {
        for (const Eigen::Vector3f& v : part.vertices) scene.object_m.extend(v.cast<double>());
    }
    append_mesh(scene.mesh, part);
    ++scene.num_parts;
}

}  // namespace object_internal

using namespace object_internal;

void validate(const ObjectSceneConfig& c) {
    auto require = [](bool ok, const std::string& key, double value, const std::string& rule) {
        if (!ok) {
            throw ConfigError("object scene: " + key + " = " + std::to_string(value) + " " + rule);
        }
    };
    require(c.box_length_m > 0.02 && c.box_length_m <= 10.0, "box_length_m", c.box_length_m,
            "must be in (0.02, 10]");
    require(c.box_width_m > 0.02 && c.box_width_m <= c.box_length_m, "box_width_m", c.box_width_m,
            "must be in (0.02, box_length_m]");
    require(c.box_height_m > 0.02 && c.box_height_m <= 10.0, "box_height_m", c.box_height_m,
            "must be in (0.02, 10]");
    require(c.plate_size_m >= 1.5 * c.box_length_m && c.plate_size_m <= 100.0, "plate_size_m",
            c.plate_size_m, "must be in [1.5 * box_length_m, 100] (the object stands on it)");
    require(c.plate_thickness_m > 0.0 && c.plate_thickness_m <= c.plate_size_m, "plate_thickness_m",
            c.plate_thickness_m, "must be in (0, plate_size_m]");
    require(c.max_edge_length_m >= 2e-4 && c.max_edge_length_m <= 0.05, "max_edge_length_m",
            c.max_edge_length_m, "must be in [0.0002, 0.05]");
}

ObjectScene make_object_scene(const ObjectSceneConfig& c) {
    validate(c);
    Rng rng(c.seed);
    const float edge = static_cast<float>(c.max_edge_length_m);
    const float L = static_cast<float>(c.box_length_m);
    const float W = static_cast<float>(c.box_width_m);
    const float H = static_cast<float>(c.box_height_m);
    const float lid_h = 0.15f * H;  // the lid overhangs the box by 2 % of its length
    const float overhang = 0.02f * L;
    ObjectScene scene;
    const Eigen::Affine3f identity = Eigen::Affine3f::Identity();

    // The turntable plate (a thin square slab; its top is the plane z = 0).
    const float P = static_cast<float>(c.plate_size_m) / 2.0f;
    add_part(scene, make_box_mesh({-P, -P, -static_cast<float>(c.plate_thickness_m)}, {P, P, 0.0f}),
             identity, edge, false);

    // The shoebox, turned a little about z, and its lid.
    const float yaw = static_cast<float>(rng.uniform(-0.35, 0.35));
    const Eigen::Affine3f box_pose(Eigen::AngleAxisf(yaw, Eigen::Vector3f::UnitZ()));
    add_part(scene, make_box_mesh({-L / 2, -W / 2, 0.0f}, {L / 2, W / 2, H - lid_h}), box_pose,
             edge, true);
    add_part(scene,
             make_box_mesh({-L / 2 - overhang, -W / 2 - overhang, H - lid_h},
                           {L / 2 + overhang, W / 2 + overhang, H}),
             box_pose, edge, true);

    // On the lid: a cylinder (a can), an ellipsoid (a stone) and a tilted small box.
    const float can_r = 0.1f * W + 0.01f;
    const float can_x = static_cast<float>(rng.uniform(0.18, 0.28)) * L;
    const float can_y = static_cast<float>(rng.uniform(-0.1, 0.1)) * W;
    add_part(scene, make_grid_cylinder_mesh(can_r, 0.6f * H, edge),
             box_pose * Eigen::Translation3f(can_x, can_y, H), edge, true);

    const Eigen::Vector3f stone_r(0.12f * L, 0.2f * W, 0.3f * H);
    const float stone_x = -static_cast<float>(rng.uniform(0.15, 0.25)) * L;
    add_part(scene, make_ellipsoid_mesh(stone_r, 4),
             box_pose * Eigen::Translation3f(stone_x, 0.0f, H + 0.6f * stone_r.z()), edge, true);

    const float tilt = static_cast<float>(rng.uniform(0.2, 0.4));
    const float s = 0.12f * L;
    add_part(scene, make_box_mesh({-s / 2, -s / 2, 0.0f}, {s / 2, s / 2, 0.5f * s}),
             box_pose * Eigen::Translation3f(0.02f * L, -0.25f * W, H) *
                 Eigen::AngleAxisf(tilt, Eigen::Vector3f::UnitX()) *
                 Eigen::AngleAxisf(0.5f, Eigen::Vector3f::UnitZ()),
             edge, true);

    // Beside the box: a taller, thinner cylinder (a bottle) on the plate.
    const float bottle_angle = static_cast<float>(rng.uniform(0.0, 2.0 * M_PI));
    const float bottle_r = 0.1f * W;
    const float bottle_dist =
        0.5f * std::hypot(L + 2.0f * overhang, W + 2.0f * overhang) + bottle_r + 0.01f;
    add_part(scene, make_grid_cylinder_mesh(bottle_r, 1.6f * H, edge),
             Eigen::Affine3f(Eigen::Translation3f(bottle_dist * std::cos(bottle_angle),
                                                  bottle_dist * std::sin(bottle_angle), 0.0f)),
             edge, true);
    return scene;
}

}  // namespace shine::sim
