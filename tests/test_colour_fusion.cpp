// Colour fusion on analytic scenes: z-buffers against the ray caster, occlusion (a red box in
// front of a blue wall), silhouette margins, neighbour filling, reflectance voxels, and the
// photometric yardstick.
#include <gtest/gtest.h>

#include <cmath>

#include "shine/colour/camera_view.hpp"
#include "shine/colour/colour_fusion.hpp"
#include "shine/colour/mesh_raster.hpp"
#include "shine/colour/photometric_score.hpp"
#include "shine/colour/reflectance_voxels.hpp"
#include "shine/core/error.hpp"
#include "shine/geometry/ray_caster.hpp"

namespace shine {
namespace {

constexpr double kDepthToleranceM = 1e-4;  // float vertices, double rays

RigCamera test_camera() {
    RigCamera camera;
    camera.name = "test";
    camera.width = 160;
    camera.height = 120;
    camera.fx = camera.fy = 100.0;
    camera.cx = 79.5;
    camera.cy = 59.5;
    return camera;
}

/// A rectangle in the plane z = depth_m spanning [x0, x1] x [y0, y1], as two triangles, with one
/// colour on its four vertices.
void add_rectangle(TriangleMesh& mesh, double x0, double x1, double y0, double y1, double depth_m,
                   std::array<std::uint8_t, 3> rgb) {
    const int base = static_cast<int>(mesh.vertices.size());
    for (const auto& [x, y] : {std::pair{x0, y0}, {x1, y0}, {x1, y1}, {x0, y1}}) {
        mesh.vertices.emplace_back(static_cast<float>(x), static_cast<float>(y),
                                   static_cast<float>(depth_m));
        mesh.vertex_rgb.push_back(rgb);
    }
    mesh.triangles.emplace_back(base, base + 1, base + 2);
    mesh.triangles.emplace_back(base, base + 2, base + 3);
}

/// A camera at `centre_map` with the identity orientation (optical frame = map frame: looking
/// along +z).
Eigen::Isometry3d camera_at(const Eigen::Vector3d& centre_map) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.translation() = centre_map;
    return T;
}

constexpr std::array<std::uint8_t, 3> kBlue{20, 40, 220};
constexpr std::array<std::uint8_t, 3> kRed{230, 30, 10};

/// A blue wall at z = 10 and a red box face at z = 6 in front of its middle.
TriangleMesh wall_and_box() {
    TriangleMesh mesh;
    add_rectangle(mesh, -20, 20, -10, 10, 10.0, kBlue);
    add_rectangle(mesh, -1, 1, -1, 1, 6.0, kRed);
    return mesh;
}

/// A view of `scene` as its camera would photograph it (the scene's own colours rendered).
CameraView photograph(const TriangleMesh& scene, const Eigen::Vector3d& centre_map) {
    CameraView view;
    view.camera = test_camera();
    view.T_map_camera = camera_at(centre_map);
    view.image =
        render_vertex_colours(scene, scene.vertex_rgb, view.camera, view.T_map_camera).image;
    return view;
}

TEST(MeshRaster, DepthMatchesTheRayCasterPixelByPixel) {
    const TriangleMesh scene = wall_and_box();
    const RigCamera camera = test_camera();
    const Eigen::Isometry3d T_map_camera = camera_at({0.4, -0.3, 0.0});
    const MeshRaster raster = rasterize_mesh(scene, camera, T_map_camera);
    const RayCaster caster(scene);
    std::size_t box_pixels = 0, compared = 0;
    for (int v = 0; v < camera.height; v += 3) {
        for (int u = 0; u < camera.width; u += 3) {
            const Eigen::Vector3d ray = camera.pixel_ray(u, v);
            const RayHit hit = caster.cast(T_map_camera.translation(), T_map_camera.linear() * ray);
            const std::size_t i = raster.index(u, v);
            ASSERT_EQ(hit.hit(), raster.triangle[i] >= 0) << "pixel " << u << "," << v;
            if (!hit.hit()) continue;
            // The raster stores z; the ray caster the distance along the unit ray.
            EXPECT_NEAR(raster.depth_m[i], hit.distance_m * ray.z(), kDepthToleranceM);
            EXPECT_EQ(raster.triangle[i] / 2, hit.triangle_id / 2);  // the same rectangle
            box_pixels += raster.triangle[i] >= 2;
            ++compared;
        }
    }
    EXPECT_GT(box_pixels, 20u);
    EXPECT_GT(compared, box_pixels + 500);
}

TEST(MeshRaster, LeavesOutTrianglesBehindOrAtTheCamera) {
    const TriangleMesh scene = wall_and_box();
    // Between the box (z = 6) and the wall, looking away from both.
    Eigen::Isometry3d T_map_camera = camera_at({0, 0, 8});
    T_map_camera.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitY()).toRotationMatrix();
    const MeshRaster raster = rasterize_mesh(scene, test_camera(), T_map_camera);
    for (std::size_t i = 0; i < raster.triangle.size(); ++i) {
        ASSERT_TRUE(raster.triangle[i] == -1 || raster.triangle[i] >= 2);  // only the box
    }
    EXPECT_NEAR(raster.depth_m[raster.index(80, 60)], 2.0, kDepthToleranceM);
}

/// Points on the wall straight behind the box, and their normals (facing the cameras).
std::vector<Eigen::Vector3d> wall_points_behind_box() {
    std::vector<Eigen::Vector3d> points;
    for (double x = -0.5; x <= 0.5; x += 0.25) {
        for (double y = -0.5; y <= 0.5; y += 0.25) points.emplace_back(x, y, 10.0);
    }
    return points;
}

TEST(ColourFusion, AWallBehindABoxTakesTheWallsColourNotTheBoxs) {
    const TriangleMesh scene = wall_and_box();
    // One camera sees the box in front of the wall's middle; the other, 6 m to the side, sees
    // the wall's middle past the box.
    const std::vector<CameraView> views = {photograph(scene, {0, 0, 0}),
                                           photograph(scene, {6, 0, 0})};
    std::vector<MeshRaster> rasters;
    for (const CameraView& view : views) {
        rasters.push_back(rasterize_mesh(scene, view.camera, view.T_map_camera));
    }
    const std::vector<Eigen::Vector3d> points = wall_points_behind_box();
    const std::vector<Eigen::Vector3d> normals(points.size(), Eigen::Vector3d(0, 0, -1));
    const FusedColours fused = fuse_colours(points, normals, views, rasters);
    ASSERT_EQ(fused.coloured, points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(fused.rgb[i][c], kBlue[c], 1) << "point " << i;
    }
    // Without the occlusion test (any depth accepted) the box's red bleeds onto the wall.
    ColourFusionConfig blind;
    blind.depth_tolerance_m = 1e3;
    const FusedColours bled = fuse_colours(points, normals, views, rasters, blind);
    EXPECT_GT(bled.rgb[points.size() / 2][0], 80);

    // The box itself is red from the camera that sees it, and nobody else.
    const FusedColours box = fuse_colours({{0.0, 0.0, 6.0}}, {{0.0, 0.0, -1.0}}, views, rasters);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(box.rgb[0][c], kRed[c], 1);
}

TEST(ColourFusion, SilhouetteMarginKeepsAnOccludersEdgeOffTheSurfaceBehind) {
    const TriangleMesh scene = wall_and_box();
    const std::vector<CameraView> views = {photograph(scene, {0, 0, 0})};
    const std::vector<MeshRaster> rasters = {
        rasterize_mesh(scene, views[0].camera, views[0].T_map_camera)};
    // The box's edge (x = 1 m at z = 6) is at column 96.17; a wall point at x = 1.75 m lands in
    // column 97, the first clear of the box, and one at x = 3 m far from it.
    const std::vector<Eigen::Vector3d> points = {{1.75, 0.0, 10.0}, {3.0, 0.0, 10.0}};
    const std::vector<Eigen::Vector3d> normals(2, Eigen::Vector3d(0, 0, -1));
    const FusedColours fused = fuse_colours(points, normals, views, rasters);
    EXPECT_EQ(fused.weight[0], 0.0f);  // too near the silhouette to trust
    EXPECT_GT(fused.weight[1], 0.0f);
    ColourFusionConfig no_margin;
    no_margin.edge_margin_px = 0;
    EXPECT_GT(fuse_colours(points, normals, views, rasters, no_margin).weight[0], 0.0f);
}

TEST(ColourFusion, GrazingAndFarViewsAreIgnored) {
    const TriangleMesh scene = wall_and_box();
    const std::vector<CameraView> views = {photograph(scene, {0, 0, 0})};
    const std::vector<MeshRaster> rasters = {
        rasterize_mesh(scene, views[0].camera, views[0].T_map_camera)};
    const std::vector<Eigen::Vector3d> points = {{3.0, 0.0, 10.0}};
    // A normal almost perpendicular to the direction to the camera, (-3, 0, -10) / 10.44.
    const Eigen::Vector3d grazing = Eigen::Vector3d(10.0, 0.0, -3.5).normalized();
    EXPECT_EQ(fuse_colours(points, {grazing}, views, rasters).coloured, 0u);
    EXPECT_EQ(fuse_colours(points, {Eigen::Vector3d(0.0, 0.0, -1.0)}, views, rasters).coloured, 1u);
    ColourFusionConfig near_only;
    near_only.max_range_m = 5.0;
    EXPECT_EQ(fuse_colours(points, {{0.0, 0.0, -1.0}}, views, rasters, near_only).coloured, 0u);
}

TEST(ColourFusion, RejectsMismatchedInputs) {
    const TriangleMesh scene = wall_and_box();
    const std::vector<CameraView> views = {photograph(scene, {0, 0, 0})};
    EXPECT_THROW(fuse_colours({{0, 0, 10}}, {}, views, {}), DataError);
}

TEST(PhotometricScore, ARenderingOfTheTruthScoresInfinitelyAndAWrongColourFinitely) {
    const TriangleMesh scene = wall_and_box();
    const CameraView view = photograph(scene, {0.5, 0, 0});
    const ColourRendering same =
        render_vertex_colours(scene, scene.vertex_rgb, view.camera, view.T_map_camera);
    const PhotometricScore perfect = score_rendering(same, view.image);
    EXPECT_TRUE(std::isinf(perfect.psnr_db));
    EXPECT_NEAR(perfect.hit_share, 1.0, 1e-9);  // the wall fills the image
    // All vertices 10 levels off in every channel: MSE 100, PSNR 10 log10(255^2 / 100).
    std::vector<std::array<std::uint8_t, 3>> off = scene.vertex_rgb;
    for (auto& rgb : off) {
        for (auto& c : rgb) c = static_cast<std::uint8_t>(c + 10);
    }
    const PhotometricScore score = score_rendering(
        render_vertex_colours(scene, off, view.camera, view.T_map_camera), view.image);
    EXPECT_NEAR(score.mse, 100.0, 1e-9);
    EXPECT_NEAR(score.psnr_db, 10.0 * std::log10(255.0 * 255.0 / 100.0), 1e-9);
}

TEST(PhotometricScore, NaiveBaselineTakesTheNearestCameraWithoutOcclusion) {
    const TriangleMesh scene = wall_and_box();
    // Vertices on the wall behind the box: the nearest camera sees the box in their direction,
    // and the baseline, without an occlusion test, paints them red.
    TriangleMesh wall;
    for (const Eigen::Vector3d& p : wall_points_behind_box())
        wall.vertices.push_back(p.cast<float>());
    const std::vector<CameraView> views = {photograph(scene, {0, 0, 0}),
                                           photograph(scene, {6, 0, -3})};
    const auto rgb = nearest_camera_colours(wall, views);
    const std::size_t middle = wall.vertices.size() / 2;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(rgb[middle][c], kRed[c], 1);  // the box's colour
}

TEST(ReflectanceVoxels, ReadsTheMeanIntensityOfNearbyPoints) {
    ReflectanceVoxels voxels(0.1);
    std::vector<Eigen::Vector3d> points;
    std::vector<float> intensity;
    for (double x = -2.0; x <= 2.0; x += 0.02) {
        for (double y = -1.0; y <= 1.0; y += 0.02) {
            points.emplace_back(x, y, 0.0);
            intensity.push_back(x < 0.0 ? 0.2f : 0.8f);
        }
    }
    points.emplace_back(0.5, 0.5, 0.0);
    intensity.push_back(std::nanf(""));  // skipped
    voxels.add(points, intensity);
    EXPECT_EQ(voxels.num_points(), points.size() - 1);
    EXPECT_NEAR(voxels.at({-1.0, 0.0, 0.0}), 0.2f, 1e-6);
    EXPECT_NEAR(voxels.at({1.0, 0.3, 0.01}), 0.8f, 1e-6);
    const float edge = voxels.at({0.0, 0.0, 0.0});
    EXPECT_GT(edge, 0.3f);
    EXPECT_LT(edge, 0.7f);
    EXPECT_TRUE(std::isnan(voxels.at({0.0, 0.0, 1.0})));  // nothing measured there
    EXPECT_THROW(voxels.add(points, {}), DataError);
    EXPECT_THROW(ReflectanceVoxels(0.0), ConfigError);
}

}  // namespace
}  // namespace shine
