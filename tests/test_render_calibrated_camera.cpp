// render_calibrated_camera on analytic scenes: a wall of two colours straight ahead of a camera,
// and random triangles whose 8-bit picture must be the colour yardstick's own rendering.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include "shine/colour/photometric_score.hpp"
#include "shine/core/error.hpp"
#include "shine/render/calibrated_camera.hpp"

namespace shine {
namespace {

constexpr double kWallM = 5.0;  // the wall's distance ahead of the camera
constexpr Rgb kRed = {200, 30, 40};
constexpr Rgb kGreen = {20, 180, 60};

RigCamera small_camera() {
    RigCamera camera;
    camera.name = "front";
    camera.fx = camera.fy = 50.0;
    camera.cx = 31.5;
    camera.cy = 23.5;
    camera.width = 64;
    camera.height = 48;
    return camera;
}

/// A wall at optical z = kWallM, 20 m square: the left half (x < 0) and the right half are two
/// quads with their own vertices, so colours do not blend across x = 0.
TriangleMesh two_colour_wall(bool with_rgb) {
    TriangleMesh mesh;
    for (int half = 0; half < 2; ++half) {
        const float x0 = half == 0 ? -10.0f : 0.0f, x1 = x0 + 10.0f;
        const int base = static_cast<int>(mesh.vertices.size());
        mesh.vertices.emplace_back(x0, -10.0f, kWallM);
        mesh.vertices.emplace_back(x1, -10.0f, kWallM);
        mesh.vertices.emplace_back(x1, 10.0f, kWallM);
        mesh.vertices.emplace_back(x0, 10.0f, kWallM);
        mesh.triangles.emplace_back(base, base + 1, base + 2);
        mesh.triangles.emplace_back(base, base + 2, base + 3);
        const Rgb c = half == 0 ? kRed : kGreen;
        if (with_rgb) {
            for (int k = 0; k < 4; ++k) mesh.vertex_rgb.push_back({c.r, c.g, c.b});
        }
    }
    return mesh;
}

TEST(CalibratedCamera, TwoColourWallStraightAhead) {
    const RigCamera camera = small_camera();
    const TriangleMesh mesh = two_colour_wall(true);
    const CalibratedCameraRendering r =
        render_calibrated_camera(mesh, camera, Eigen::Isometry3d::Identity());
    EXPECT_EQ(r.shading, CameraShading::kVertexColour);
    const ExrImage& layers = r.layers;
    ASSERT_EQ(layers.width(), 64);
    ASSERT_EQ(layers.height(), 48);
    constexpr double kRangeToleranceM = 1e-4;  // float vertices and float channels
    for (int v = 0; v < 48; ++v) {
        for (int u = 0; u < 64; ++u) {
            const std::size_t i = static_cast<std::size_t>(v) * 64 + u;
            ASSERT_TRUE(r.picture.hit[i]) << u << "," << v;
            EXPECT_EQ(r.picture.image.at(u, v), u < 32 ? kRed : kGreen) << u << "," << v;
            const double expected_range = kWallM / camera.pixel_ray(u, v).z();
            EXPECT_NEAR(layers.channel("range.V")[i], expected_range, kRangeToleranceM);
            // The wall faces the camera: its normal points back along -z.
            EXPECT_FLOAT_EQ(layers.channel("normal.Z")[i], -1.0f);
        }
    }
    // Linear light: 200 in sRGB is 0.578 linear, 30 is 0.0130.
    const std::size_t left = 10 * 64 + 5;
    EXPECT_NEAR(layers.channel("color.R")[left], srgb_to_linear(200.0 / 255.0), 1e-6);
    EXPECT_NEAR(layers.channel("color.R")[left], 0.5776, 1e-4);
    EXPECT_NEAR(layers.channel("color.G")[left], 0.0130, 1e-4);
    EXPECT_FALSE(layers.has_channel("intensity.V"));
}

TEST(CalibratedCamera, PixelsBesideTheWallShowNothing) {
    // A camera 12 m left of the wall's centre sees the wall's left edge (x = -10 m) in its
    // columns from u = 51.5 on; the columns left of it show nothing.
    const RigCamera camera = small_camera();
    TriangleMesh mesh = two_colour_wall(true);
    Eigen::Isometry3d T_map_camera = Eigen::Isometry3d::Identity();
    T_map_camera.translation() = Eigen::Vector3d(-12.0, 0.0, 0.0);
    const CalibratedCameraRendering r = render_calibrated_camera(mesh, camera, T_map_camera);
    std::size_t hits = 0;
    for (std::size_t i = 0; i < r.picture.hit.size(); ++i) {
        const bool finite = !std::isnan(r.layers.channel("range.V")[i]);
        EXPECT_EQ(finite, r.picture.hit[i] != 0);
        EXPECT_EQ(finite, !std::isnan(r.layers.channel("color.G")[i]));
        hits += r.picture.hit[i];
    }
    EXPECT_EQ(hits, 12u * 48u);
    EXPECT_EQ(r.picture.image.at(51, 20), (Rgb{0, 0, 0}));
    EXPECT_EQ(r.picture.image.at(52, 20), kRed);
}

TEST(CalibratedCamera, PictureIsTheColourYardsticksRendering) {
    // 200 random triangles with random vertex colours 3 to 12 m ahead: every pixel of the 8-bit
    // picture equals render_vertex_colours' (the held-out PSNR's rendering), hit mask included.
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> xy(-6.0f, 6.0f), z(3.0f, 12.0f), jitter(-1.5f, 1.5f);
    std::uniform_int_distribution<int> byte(0, 255);
    TriangleMesh mesh;
    for (int t = 0; t < 200; ++t) {
        const Eigen::Vector3f centre(xy(rng), xy(rng), z(rng));
        const int base = static_cast<int>(mesh.vertices.size());
        for (int k = 0; k < 3; ++k) {
            mesh.vertices.push_back(centre +
                                    Eigen::Vector3f(jitter(rng), jitter(rng), jitter(rng)));
            mesh.vertex_rgb.push_back({static_cast<std::uint8_t>(byte(rng)),
                                       static_cast<std::uint8_t>(byte(rng)),
                                       static_cast<std::uint8_t>(byte(rng))});
        }
        mesh.triangles.emplace_back(base, base + 1, base + 2);
    }
    const RigCamera camera = small_camera();
    Eigen::Isometry3d T_map_camera = Eigen::Isometry3d::Identity();
    T_map_camera.linear() =
        Eigen::AngleAxisd(0.1, Eigen::Vector3d(0.2, 1.0, 0.1).normalized()).toRotationMatrix();
    T_map_camera.translation() = Eigen::Vector3d(0.3, -0.2, 0.1);
    const CalibratedCameraRendering r = render_calibrated_camera(mesh, camera, T_map_camera);
    const ColourRendering reference =
        render_vertex_colours(mesh, mesh.vertex_rgb, camera, T_map_camera);
    EXPECT_EQ(r.picture.hit, reference.hit);
    EXPECT_EQ(r.picture.image.pixels(), reference.image.pixels());
    std::size_t hits = 0;
    for (const std::uint8_t h : r.picture.hit) hits += h;
    EXPECT_GT(hits, r.picture.hit.size() / 4);  // the scene is not empty
    const PhotometricScore self = score_rendering(r.picture, reference.image);
    EXPECT_TRUE(std::isinf(self.psnr_db));
    // At another exposure both scale alike (clamped at 255), and the picture changes.
    for (const double gain : {0.8, 1.3}) {
        const CalibratedCameraRendering scaled =
            render_calibrated_camera(mesh, camera, T_map_camera, gain);
        EXPECT_EQ(scaled.picture.image.pixels(),
                  render_vertex_colours(mesh, mesh.vertex_rgb, camera, T_map_camera, gain)
                      .image.pixels());
        EXPECT_NE(scaled.picture.image.pixels(), reference.image.pixels());
        float brightest = 0.0f;  // linear light, NaN where no surface
        for (const float value : scaled.layers.channel("color.R")) {
            if (!std::isnan(value)) brightest = std::max(brightest, value);
        }
        EXPECT_LE(brightest, 1.0f);
        if (gain > 1.0) EXPECT_EQ(brightest, 1.0f);  // some red of 200+ went past 255
    }
}

TEST(CalibratedCamera, WithoutColoursIntensityIsGrey) {
    TriangleMesh mesh = two_colour_wall(false);
    // Left half 0.2, right half 0.4: the 99th percentile (0.4) is white.
    for (int k = 0; k < 8; ++k) mesh.vertex_intensity.push_back(k < 4 ? 0.2f : 0.4f);
    const CalibratedCameraRendering r =
        render_calibrated_camera(mesh, small_camera(), Eigen::Isometry3d::Identity());
    EXPECT_EQ(r.shading, CameraShading::kIntensity);
    EXPECT_DOUBLE_EQ(r.intensity_white, 0.4f);
    EXPECT_EQ(r.picture.image.at(5, 20), (Rgb{128, 128, 128}));
    EXPECT_EQ(r.picture.image.at(60, 20), (Rgb{255, 255, 255}));
    EXPECT_NEAR(r.layers.channel("intensity.V")[20 * 64 + 5], 0.2, 1e-6);
    EXPECT_FALSE(r.layers.has_channel("color.R"));
    // An unknown intensity at the right half's corner (0, -10) that both its triangles share:
    // the right half has none (NaN, black).
    mesh.vertex_intensity[4] = std::numeric_limits<float>::quiet_NaN();
    const CalibratedCameraRendering unknown =
        render_calibrated_camera(mesh, small_camera(), Eigen::Isometry3d::Identity());
    std::size_t nan_pixels = 0;
    for (const float x : unknown.layers.channel("intensity.V")) nan_pixels += std::isnan(x);
    EXPECT_EQ(nan_pixels, 32u * 48u);
    EXPECT_EQ(unknown.picture.image.at(60, 20), (Rgb{0, 0, 0}));
    EXPECT_EQ(unknown.picture.hit[20 * 64 + 60], 1);
}

TEST(CalibratedCamera, WithoutColoursOrIntensityShadedGrey) {
    const CalibratedCameraRendering r = render_calibrated_camera(
        two_colour_wall(false), small_camera(), Eigen::Isometry3d::Identity());
    EXPECT_EQ(r.shading, CameraShading::kShadedGrey);
    // Near the image centre the ray meets the wall head-on: 255 * (0.25 + 0.75 cos), cos ~ 1.
    EXPECT_EQ(r.picture.image.at(31, 23), (Rgb{255, 255, 255}));
    // At a corner the ray is 38 degrees off the wall's normal: darker.
    EXPECT_LT(r.picture.image.at(0, 0).r, 235);
    EXPECT_GT(r.picture.image.at(0, 0).r, 200);
}

TEST(CalibratedCamera, MismatchedAppearanceIsAnError) {
    TriangleMesh mesh = two_colour_wall(true);
    mesh.vertex_rgb.pop_back();
    EXPECT_THROW(render_calibrated_camera(mesh, small_camera(), Eigen::Isometry3d::Identity()),
                 DataError);
    EXPECT_THROW(
        render_calibrated_camera(TriangleMesh{}, small_camera(), Eigen::Isometry3d::Identity()),
        DataError);
}

}  // namespace
}  // namespace shine
