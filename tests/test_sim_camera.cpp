// The simulator's camera and the street's true colours: a pixel shows the albedo where its ray
// first meets the scene; a nearer object hides the wall behind it; the albedo is textured,
// distinct per object and deterministic; images do not depend on the thread count; camera.yaml
// reads back exactly.
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <tuple>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/geometry/ray_caster.hpp"
#include "shine/sim/camera_simulator.hpp"
#include "shine/sim/mesh_primitives.hpp"
#include "shine/sim/moving_scene.hpp"
#include "shine/sim/scene_albedo.hpp"
#include "shine/sim/street_scene.hpp"

namespace shine::sim {
namespace {

/// A 40 m street (about 0.2 s to build).
StreetSceneConfig small_street_config() {
    StreetSceneConfig config;
    config.seed = 3;
    config.start_x_m = -10.0;
    config.length_m = 40.0;
    return config;
}

/// A small camera (160 x 60 pixels, 90 deg wide) on the front mount.
CameraConfig small_camera() {
    CameraConfig camera;
    camera.width = 160;
    camera.height = 60;
    camera.fx = camera.fy = 80.0;
    camera.cx = 79.5;
    camera.cy = 29.5;
    return camera;
}

/// The LiDAR 1.73 m above the road, 2 m right of the centre line, looking along the street (+x),
/// turned 10 deg to the left so that one side's facades fill part of the image.
Eigen::Isometry3d lidar_pose() {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = Eigen::Vector3d(-5.0, -2.0, 1.73);
    T.linear() = Eigen::AngleAxisd(10.0 * M_PI / 180.0, Eigen::Vector3d::UnitZ()).matrix();
    return T;
}

std::tuple<int, int, int> key(Rgb c) { return {c.r, c.g, c.b}; }

TEST(SimCamera, FrontMountIsKittiLikeAndLooksAlongTheLidarsX) {
    const Eigen::Isometry3d T = front_camera_mount();
    // Optical z (forward) = LiDAR +x, optical y (down) = LiDAR -z, optical x (right) = LiDAR -y.
    EXPECT_TRUE(T.linear().col(2).isApprox(Eigen::Vector3d::UnitX()));
    EXPECT_TRUE(T.linear().col(1).isApprox(-Eigen::Vector3d::UnitZ()));
    EXPECT_TRUE(T.linear().col(0).isApprox(-Eigen::Vector3d::UnitY()));
    EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-12);
    EXPECT_TRUE(T.translation().isApprox(Eigen::Vector3d(0.27, 0.0, -0.08)));
    // The pixel convention: the principal point looks straight ahead; u to the right is -y.
    const CameraConfig camera;
    EXPECT_TRUE(
        camera_ray_optical(camera, camera.cx, camera.cy).isApprox(Eigen::Vector3d::UnitZ()));
    const Eigen::Vector3d right = camera_ray_optical(camera, camera.cx + camera.fx, camera.cy);
    EXPECT_TRUE(right.isApprox(Eigen::Vector3d(1.0, 0.0, 1.0).normalized()));
}

TEST(SimCamera, EveryPixelShowsTheAlbedoWhereItsRayHits) {
    const StreetSceneConfig config = small_street_config();
    const StreetScene scene = make_street_scene(config);
    const RayCaster caster(scene.mesh);
    const SceneAlbedo albedo(scene, config);
    const CameraConfig camera = small_camera();
    const RgbImage image = render_camera_image(caster, albedo, camera, lidar_pose());
    ASSERT_EQ(image.width(), camera.width);
    ASSERT_EQ(image.height(), camera.height);

    // Each pixel's ray, built here from the documented convention (not camera_ray_optical).
    const Eigen::Isometry3d T_world_camera = lidar_pose() * front_camera_mount();
    int sky = 0;
    std::set<std::tuple<int, int, int>> colours;
    for (int v = 0; v < camera.height; ++v) {
        for (int u = 0; u < camera.width; ++u) {
            const Eigen::Vector3d d_optical =
                Eigen::Vector3d((u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, 1.0)
                    .normalized();
            const Eigen::Vector3d origin = T_world_camera.translation();
            const Eigen::Vector3d direction = T_world_camera.linear() * d_optical;
            const RayHit hit = caster.cast(origin, direction);
            const Rgb expected =
                hit.hit() ? albedo.at(hit.triangle_id, origin + hit.distance_m * direction)
                          : kSkyColour;
            ASSERT_EQ(key(image.at(u, v)), key(expected)) << "pixel (" << u << ", " << v << ")";
            sky += hit.hit() ? 0 : 1;
            colours.insert(key(expected));
        }
    }
    // The view holds sky, road and buildings: many colours, not one.
    const int pixels = camera.width * camera.height;
    EXPECT_GT(sky, pixels / 20);
    EXPECT_LT(sky, pixels / 2);
    EXPECT_GE(colours.size(), 15u);
    // The bottom row's centre is the road ahead (asphalt or a marking), never the sky.
    EXPECT_NE(key(image.at(camera.width / 2, camera.height - 1)), key(kSkyColour));
}

TEST(SimCamera, AnObjectInFrontOfAWallShowsItsOwnColour) {
    // A building's wall 10 m ahead (object 1) and a car body 5 m ahead (object 2), hand-built.
    StreetScene scene;
    scene.mesh = make_box_mesh({10.0f, -10.0f, 0.0f}, {11.0f, 10.0f, 6.0f});
    ScenePart wall;
    wall.kind = SceneObjectKind::kBuilding;
    wall.surface = ScenePartSurface::kBuildingBlock;
    wall.object_index = 1;
    wall.num_triangles = scene.mesh.triangles.size();
    scene.parts.push_back(wall);
    append_mesh(scene.mesh, make_box_mesh({5.0f, -0.5f, 1.0f}, {6.0f, 0.5f, 2.0f}));
    ScenePart car;
    car.kind = SceneObjectKind::kCar;
    car.surface = ScenePartSurface::kCarBody;
    car.object_index = 2;
    car.first_triangle = wall.num_triangles;
    car.num_triangles = scene.mesh.triangles.size() - wall.num_triangles;
    scene.parts.push_back(car);

    const RayCaster caster(scene.mesh);
    const SceneAlbedo albedo(scene, StreetSceneConfig());
    CameraConfig camera = small_camera();
    camera.T_lidar_camera = front_camera_mount();
    Eigen::Isometry3d T_world_lidar = Eigen::Isometry3d::Identity();
    // The camera 1.5 m above the ground: its centre pixel looks at the car's middle.
    T_world_lidar.translation() = Eigen::Vector3d(0.0, 0.0, 1.58);
    const RgbImage image = render_camera_image(caster, albedo, camera, T_world_lidar);

    SurfacePoint on_car;
    on_car.surface = ScenePartSurface::kCarBody;
    on_car.object_index = 2;
    on_car.point_m = Eigen::Vector3d(5.0, 0.0, 1.5);
    on_car.normal = -Eigen::Vector3d::UnitX();
    const Rgb car_colour = surface_albedo(on_car, albedo.cross_section());
    SurfacePoint behind = on_car;
    behind.surface = ScenePartSurface::kBuildingBlock;
    behind.object_index = 1;
    behind.point_m = Eigen::Vector3d(10.0, 0.0, 1.5);
    const Rgb wall_colour = surface_albedo(behind, albedo.cross_section());
    ASSERT_NE(key(car_colour), key(wall_colour));
    // Pixel (80, 30) is just right of and below the centre: on the car, whose face spans
    // +-0.5 m at 5 m (+-8 pixels).
    EXPECT_EQ(key(image.at(80, 30)), key(car_colour));
    // Far to the side the ray passes the car and meets the wall.
    const Rgb side = image.at(10, 30);
    EXPECT_NE(key(side), key(car_colour));
    EXPECT_NE(key(side), key(kSkyColour));
    // The car hides exactly the pixels whose rays reach it first: count them against its
    // angular size, 1 m x 1 m at 5 m with f = 80 px: 16 x 16 pixels.
    int car_pixels = 0;
    for (int v = 0; v < camera.height; ++v) {
        for (int u = 0; u < camera.width; ++u) car_pixels += image.at(u, v) == car_colour ? 1 : 0;
    }
    EXPECT_NEAR(car_pixels, 16 * 16, 2 * 16 + 2 * 16);  // the border rows may go either way
}

TEST(SimCamera, MoversAreSeenWhereTheyAreAtTheImagesTime) {
    const TriangleMesh wall = make_box_mesh({20.0f, -20.0f, -1.0f}, {21.0f, 20.0f, 9.0f});
    StreetScene scene;
    scene.mesh = wall;
    ScenePart part;
    part.kind = SceneObjectKind::kBuilding;
    part.surface = ScenePartSurface::kBuildingBlock;
    part.num_triangles = wall.triangles.size();
    scene.parts.push_back(part);
    const RayCaster caster(scene.mesh);
    const SceneAlbedo albedo(scene, StreetSceneConfig());
    MoverTracks tracks;
    MoverTrack car;
    car.kind = MoverKind::kCar;
    // At x = 10 until t = 1 s, then 10 m/s along +y: gone from the view's centre by t = 3 s.
    car.waypoints = {
        {0.0, {10.0, 0.0, 0.0}, 0.0}, {1.0, {10.0, 0.0, 0.0}, 0.0}, {6.0, {10.0, 50.0, 0.0}, 0.0}};
    tracks.movers = {car};
    const MovingScene moving(caster, tracks);
    Eigen::Isometry3d T_world_lidar = Eigen::Isometry3d::Identity();
    T_world_lidar.translation() = Eigen::Vector3d(0.0, 0.0, 0.83);  // the camera 0.75 m up
    const CameraConfig camera = small_camera();
    const Rgb car_colour = mover_albedo(MoverKind::kCar, 0);
    EXPECT_EQ(key(render_camera_image(moving, albedo, camera, T_world_lidar, 0.5).at(80, 30)),
              key(car_colour));
    const Rgb later = render_camera_image(moving, albedo, camera, T_world_lidar, 3.0).at(80, 30);
    EXPECT_NE(key(later), key(car_colour));
    EXPECT_NE(key(later), key(kSkyColour));
}

TEST(SceneAlbedo, FacadesAreTexturedAndDistinctPerBuilding) {
    const StreetCrossSection street;
    std::set<std::tuple<int, int, int>> all;
    std::set<std::tuple<int, int, int>> bases;
    for (std::size_t building = 0; building < 30; ++building) {
        // A facade facing the street (-y), 12 m wide and 9 m high, sampled every 0.1 m.
        std::vector<int> count_of;
        std::vector<std::tuple<int, int, int>> seen;
        bool changes_within_3m = false;
        for (int i = 0; i < 120; ++i) {
            Rgb previous{};
            for (int k = 0; k < 90; ++k) {
                SurfacePoint q;
                q.surface = ScenePartSurface::kBuildingBlock;
                q.object_index = building;
                q.point_m = Eigen::Vector3d(0.05 + 0.1 * i, 9.0, 0.05 + 0.1 * k);
                q.normal = -Eigen::Vector3d::UnitY();
                const Rgb c = surface_albedo(q, street);
                all.insert(key(c));
                const auto it = std::find(seen.begin(), seen.end(), key(c));
                if (it == seen.end()) {
                    seen.push_back(key(c));
                    count_of.push_back(1);
                } else {
                    ++count_of[it - seen.begin()];
                }
                if (k > 0 && k < 30 && c != previous) changes_within_3m = true;
                previous = c;
            }
        }
        ASSERT_GE(seen.size(), 2u) << "building " << building << " has a plain facade";
        // Texture, not a stray sample: the second most common colour covers >= 10 % of the facade.
        std::sort(count_of.rbegin(), count_of.rend());
        EXPECT_GE(count_of[1], 120 * 90 / 10) << "building " << building;
        EXPECT_TRUE(changes_within_3m) << "building " << building << ": no pattern in 3 m";
        bases.insert(seen.front());
    }
    EXPECT_GE(all.size(), 20u);   // 30 facades of 10 palette colours, 3 patterns
    EXPECT_GE(bases.size(), 6u);  // neighbours rarely share a colour
}

TEST(SceneAlbedo, GroundHasLaneMarkingsCurbsSidewalksAndGrass) {
    const StreetCrossSection street;  // road |y| < 5, sidewalks to |y| = 8, curbs 0.15 m
    auto ground = [&](double x, double y, double z, Eigen::Vector3d normal) {
        SurfacePoint q;
        q.point_m = Eigen::Vector3d(x, y, z);
        q.normal = normal;
        return key(surface_albedo(q, street));
    };
    const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
    const auto asphalt = ground(4.5, 1.0, 0.0, up);
    const auto marking = ground(1.5, 0.0, 0.0, up);  // on a dash of the centre line
    EXPECT_NE(asphalt, marking);
    EXPECT_EQ(ground(4.5, 0.0, 0.0, up), asphalt);   // between two dashes
    EXPECT_EQ(ground(1.5, -2.7, 0.0, up), marking);  // the parking lane's line
    EXPECT_EQ(ground(1.5, 2.7, 0.0, up), marking);
    const auto curb = ground(1.5, 5.0, 0.07, -Eigen::Vector3d::UnitY());
    const auto sidewalk = ground(1.5, 6.5, 0.15, up);
    const auto lot = ground(1.5, 10.5, 0.15, up);
    std::set<std::tuple<int, int, int>> distinct = {asphalt, marking, curb, sidewalk, lot};
    EXPECT_EQ(distinct.size(), 5u);
}

TEST(SceneAlbedo, CarsTreesAndPedestriansVaryPerObject) {
    const StreetCrossSection street;
    for (const ScenePartSurface surface : {ScenePartSurface::kCarBody, ScenePartSurface::kTreeCrown,
                                           ScenePartSurface::kPedestrianTorso}) {
        std::set<std::tuple<int, int, int>> colours;
        for (std::size_t object = 0; object < 40; ++object) {
            SurfacePoint q;
            q.surface = surface;
            q.object_index = object;
            q.point_m = Eigen::Vector3d(0.25, 0.25, 1.25);
            colours.insert(key(surface_albedo(q, street)));
        }
        EXPECT_GE(colours.size(), 5u) << to_string(surface);
    }
}

TEST(SceneAlbedo, TheSameStreetGivesTheSameColoursAndImages) {
    const StreetSceneConfig config = small_street_config();
    const StreetScene a = make_street_scene(config);
    const StreetScene b = make_street_scene(config);
    const RayCaster caster_a(a.mesh);
    const RayCaster caster_b(b.mesh);
    const SceneAlbedo albedo_a(a, config);
    const SceneAlbedo albedo_b(b, config);
    const CameraConfig camera = small_camera();
    RgbImage one_thread(1, 1);
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        one_thread = render_camera_image(caster_a, albedo_a, camera, lidar_pose());
    }
    const RgbImage all_threads = render_camera_image(caster_b, albedo_b, camera, lidar_pose());
    EXPECT_EQ(one_thread.pixels(), all_threads.pixels());
    // Every part's surface is recorded: each kind of part of a street appears.
    std::set<ScenePartSurface> surfaces;
    for (const ScenePart& part : a.parts) surfaces.insert(part.surface);
    EXPECT_TRUE(surfaces.count(ScenePartSurface::kGround));
    EXPECT_TRUE(surfaces.count(ScenePartSurface::kBuildingBlock));
    EXPECT_TRUE(surfaces.count(ScenePartSurface::kCarBody));
    EXPECT_TRUE(surfaces.count(ScenePartSurface::kCarWheel));
    EXPECT_TRUE(surfaces.count(ScenePartSurface::kTreeCrown));
    EXPECT_TRUE(surfaces.count(ScenePartSurface::kPoleMast));
    for (const ScenePart& part : a.parts) {
        const bool matches =
            (part.kind == SceneObjectKind::kGround) == (part.surface == ScenePartSurface::kGround);
        EXPECT_TRUE(matches) << to_string(part.kind) << " part with surface "
                             << to_string(part.surface);
    }
}

TEST(SceneAlbedo, RefusesTrianglesOutsideTheMesh) {
    const StreetSceneConfig config = small_street_config();
    const StreetScene scene = make_street_scene(config);
    const SceneAlbedo albedo(scene, config);
    EXPECT_THROW(albedo.at(-1, Eigen::Vector3d::Zero()), ConfigError);
    EXPECT_THROW(
        albedo.at(static_cast<std::int32_t>(scene.mesh.triangles.size()), Eigen::Vector3d::Zero()),
        ConfigError);
    EXPECT_EQ(albedo.part_of(0).kind, SceneObjectKind::kGround);
}

TEST(SimCamera, CameraYamlReadsBackExactly) {
    CameraConfig camera;
    camera.fx = 321.123456789012;
    camera.T_lidar_camera.translation() = Eigen::Vector3d(0.27, 0.1 / 3.0, -0.08);
    const YAML::Node yaml = YAML::Load(camera_yaml(camera));
    EXPECT_EQ(yaml["width"].as<int>(), 640);
    EXPECT_EQ(yaml["height"].as<int>(), 240);
    EXPECT_EQ(yaml["fx"].as<double>(), camera.fx);
    EXPECT_EQ(yaml["fy"].as<double>(), 320.0);
    EXPECT_EQ(yaml["cx"].as<double>(), 319.5);
    EXPECT_EQ(yaml["cy"].as<double>(), 119.5);
    const YAML::Node T = yaml["T_lidar_camera"];
    ASSERT_EQ(T.size(), 12u);
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) {
            EXPECT_EQ(T[r * 4 + c].as<double>(), camera.T_lidar_camera.matrix()(r, c))
                << r << ", " << c;
        }
    }
    CameraConfig bad;
    bad.fx = 0.0;
    EXPECT_THROW(validate(bad), ConfigError);
    bad = CameraConfig();
    bad.T_lidar_camera.linear() *= 2.0;
    EXPECT_THROW(validate(bad), ConfigError);
}

}  // namespace
}  // namespace shine::sim
