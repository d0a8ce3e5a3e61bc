// The render module on analytic scenes: the spherical LiDAR model recovers a synthetic scan's
// beam layout (upright and tilted), a plane mesh rendered from a known pose gives the analytic
// range, normal and range error per pixel, and an SDF slice matches direct queries of the map.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <sstream>

#include "shine/core/error.hpp"
#include "shine/render/lidar_model.hpp"
#include "shine/render/map_render.hpp"
#include "shine/render/pinhole_camera.hpp"
#include "shine/render/sdf_slice.hpp"

namespace shine {
namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr double kDeg = kPi / 180.0;
// The ray/triangle test runs in double against float vertices: ranges agree to far below this.
constexpr double kRangeToleranceM = 1e-4;  // 0.1 mm
constexpr double kAngleToleranceDeg = 0.02;

/// 16 rings at irregular known elevations (a VLP-16 interleaves them; sorted here), 360 columns.
std::vector<double> ring_elevations_deg() {
    return {-15, -13, -11, -9, -7, -5, -3, -1, 1, 3, 5, 7, 9, 11, 13, 15.5};
}

/// A synthetic scan: each ring and column fires once, at a range of 4 to 40 m; about 10 % of
/// the returns are missing; points are rotated by `R_sensor_beams` (a tilted frame).
std::vector<Eigen::Vector3f> synthetic_scan(const Eigen::Matrix3d& R_sensor_beams, int columns) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> range(4.0, 40.0), keep(0.0, 1.0);
    std::vector<Eigen::Vector3f> points;
    for (const double e : ring_elevations_deg()) {
        for (int c = 0; c < columns; ++c) {
            if (keep(rng) < 0.1) continue;
            const double a = 2.0 * kPi * (c + 0.5) / columns;
            const Eigen::Vector3d d(std::cos(e * kDeg) * std::cos(a),
                                    std::cos(e * kDeg) * std::sin(a), std::sin(e * kDeg));
            points.push_back((R_sensor_beams * d * range(rng)).cast<float>());
        }
    }
    return points;
}

void expect_layout(const SphericalLidarModel& model, int columns) {
    const std::vector<double> expected = ring_elevations_deg();
    ASSERT_EQ(model.height(), int(expected.size()));
    EXPECT_EQ(model.width(), columns);
    for (int r = 0; r < model.height(); ++r) {
        // Row 0 is the highest ring.
        EXPECT_NEAR(model.elevations_rad[r] / kDeg, expected[expected.size() - 1 - r],
                    kAngleToleranceDeg)
            << "ring " << r;
    }
}

TEST(RenderLidarModel, RecoversRingsAndColumnsOfAnUprightScan) {
    const auto points = synthetic_scan(Eigen::Matrix3d::Identity(), 360);
    const SphericalLidarModel model = infer_spherical_lidar(points);
    expect_layout(model, 360);
    EXPECT_LT(model.tilt_deg(), kAngleToleranceDeg);
    // Every return maps back to its own ring, and the pixel's ray is within half a step of it.
    for (std::size_t i = 0; i < points.size(); i += 97) {
        int row = -1, col = -1;
        const Eigen::Vector3d d = points[i].cast<double>().normalized();
        ASSERT_TRUE(model.pixel_of(d, row, col));
        const double angle =
            std::acos(std::clamp(d.dot(model.direction_sensor(row, col)), -1.0, 1.0));
        EXPECT_LT(angle / kDeg, 0.5 + kAngleToleranceDeg) << "point " << i;
    }
}

TEST(RenderLidarModel, RecoversTheSpinAxisOfATiltedFrame) {
    // The points in a frame tilted 12 deg about x and 5 deg about y against the sensor's beams.
    const Eigen::Matrix3d R = (Eigen::AngleAxisd(12 * kDeg, Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(-5 * kDeg, Eigen::Vector3d::UnitY()))
                                  .toRotationMatrix();
    const auto points = synthetic_scan(R, 720);
    const SphericalLidarModel model = infer_spherical_lidar(points);
    expect_layout(model, 720);
    const double axis_error_deg =
        std::acos(std::clamp(model.R_sensor_beams.col(2).dot(R.col(2)), -1.0, 1.0)) / kDeg;
    EXPECT_LT(axis_error_deg, kAngleToleranceDeg);
}

TEST(RenderLidarModel, TooFewRingsIsAClearError) {
    std::vector<Eigen::Vector3f> flat;
    for (int c = 0; c < 360; ++c) {
        flat.emplace_back(10 * std::cos(c * kDeg), 10 * std::sin(c * kDeg), 0.0f);
    }
    SphericalLidarConfig config;
    config.max_tilt_deg = 0.0;
    EXPECT_THROW(infer_spherical_lidar(flat, config), DataError);
    EXPECT_THROW(infer_spherical_lidar({}, config), DataError);
}

/// A 400 m square in the plane z = 0 of a frame whose world position is `origin_world_m`.
TriangleMesh ground_plane(const Eigen::Vector3d& origin_world_m) {
    TriangleMesh mesh;
    mesh.origin_world_m = origin_world_m;
    mesh.vertices = {{-200, -200, 0}, {200, -200, 0}, {200, 200, 0}, {-200, 200, 0}};
    mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
    return mesh;
}

TEST(RenderMapView, PinholeViewOfAPlaneGivesTheAnalyticRange) {
    // A far-away map frame (UTM-like) and a camera 2.5 m above the plane looking down, yawed.
    const Eigen::Vector3d origin(500000.0, 5000000.0, 100.0);
    const TriangleMesh mesh = ground_plane(origin);
    Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
    T_world_sensor.linear() = (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(kPi - 0.2, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    T_world_sensor.translation() = origin + Eigen::Vector3d(3.0, -4.0, 2.5);
    PinholeCamera camera = parse_pinhole_camera("200,180,80.5,60,160,120");
    camera.R_sensor_camera.setIdentity();  // the optical frame is the sensor's: z forward
    const PixelRays rays = camera_pixel_rays(camera);
    const MeshRenderer renderer(mesh);
    const ExrImage image = renderer.render(rays, T_world_sensor);
    EXPECT_FALSE(image.has_channel("error.V"));
    const auto& range = image.channel("range.V");
    for (int v = 0; v < camera.height; ++v) {
        for (int u = 0; u < camera.width; ++u) {
            const std::size_t i = std::size_t(v) * camera.width + u;
            const Eigen::Vector3d d_world = T_world_sensor.linear() * rays.directions_sensor[i];
            ASSERT_LT(d_world.z(), 0.0);
            const double expected_m = 2.5 / -d_world.z();
            ASSERT_NEAR(range[i], expected_m, kRangeToleranceM) << "pixel " << u << ", " << v;
            EXPECT_FLOAT_EQ(image.channel("normal.Z")[i], 1.0f);
            EXPECT_FLOAT_EQ(image.channel("normal.X")[i], 0.0f);
        }
    }
}

TEST(RenderMapView, LidarViewOfAPlaneGivesRangeErrorAndMisses) {
    const TriangleMesh mesh = ground_plane(Eigen::Vector3d::Zero());
    Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
    T_world_sensor.translation() = Eigen::Vector3d(1.0, 2.0, 1.8);
    // Returns of the downward rings on the plane, 5 cm short (a thin layer the map lacks).
    constexpr double kShortM = 0.05;
    std::vector<Eigen::Vector3f> points;
    for (const double e : ring_elevations_deg()) {
        for (int c = 0; c < 360; ++c) {
            const double a = 2.0 * kPi * (c + 0.5) / 360;
            const Eigen::Vector3d d(std::cos(e * kDeg) * std::cos(a),
                                    std::cos(e * kDeg) * std::sin(a), std::sin(e * kDeg));
            // Upward rings see a far ceiling that is not in the mesh: returns without surface.
            const double r = d.z() < 0 ? 1.8 / -d.z() - kShortM : 30.0 / d.norm();
            points.push_back((d * r).cast<float>());
        }
    }
    const SphericalLidarModel model = infer_spherical_lidar(points);
    ASSERT_EQ(model.height(), 16);
    ASSERT_EQ(model.width(), 360);
    const PixelRays rays = scan_pixel_rays(model, points, 1.0, 150.0);
    const MeshRenderer renderer(mesh);
    const ExrImage image = renderer.render(rays, T_world_sensor);
    const auto& error = image.channel("error.V");
    const auto& measured = image.channel("measured.V");
    const auto& range = image.channel("range.V");
    int down = 0, up = 0;
    for (int row = 0; row < 16; ++row) {
        for (int col = 0; col < 360; ++col) {
            const std::size_t i = std::size_t(row) * 360 + col;
            ASSERT_FALSE(std::isnan(measured[i])) << "every pixel has a return; row " << row
                                                  << " col " << col << " tilt " << model.tilt_deg();
            if (model.elevations_rad[row] < 0) {
                ++down;
                EXPECT_NEAR(error[i], -kShortM, kRangeToleranceM);
                EXPECT_NEAR(range[i], 1.8 / std::sin(-model.elevations_rad[row]), 1e-3);
            } else {
                ++up;
                EXPECT_TRUE(std::isnan(range[i]));
                EXPECT_TRUE(std::isnan(error[i]));
            }
        }
    }
    EXPECT_EQ(down, 8 * 360);
    EXPECT_EQ(up, 8 * 360);
}

TEST(RenderMapView, PinholeCameraLooksAlongTheLidarsForwardAxisByDefault) {
    constexpr double kTolerance = 1e-12;
    const PinholeCamera camera = parse_pinhole_camera("100,100,2,1,5,3");
    const PixelRays rays = camera_pixel_rays(camera);
    // The principal point (2, 1) looks along +x; the row above it upward (+z), the column to
    // its right to the LiDAR's right (-y).
    EXPECT_TRUE(rays.directions_sensor[1 * 5 + 2].isApprox(Eigen::Vector3d::UnitX(), kTolerance));
    EXPECT_GT(rays.directions_sensor[0 * 5 + 2].z(), 0.0);
    EXPECT_LT(rays.directions_sensor[1 * 5 + 3].y(), 0.0);
    EXPECT_TRUE(parse_camera_rotation("0,0,1,-1,0,0,0,-1,0").isApprox(camera_looking_forward()));
}

TEST(RenderMapView, LookAtAimsTheImageCentreAtTheTarget) {
    constexpr double kTolerance = 1e-12;
    const Eigen::Vector3d target(3.0, -4.0, -1.0);
    const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
    const Eigen::Matrix3d R = camera_looking_at(target, up);
    EXPECT_TRUE((R.transpose() * R).isIdentity(kTolerance));
    EXPECT_NEAR(R.determinant(), 1.0, kTolerance);
    EXPECT_TRUE(R.col(2).isApprox(target.normalized(), kTolerance));
    EXPECT_NEAR(R.col(0).dot(up), 0.0, kTolerance);  // no roll: the image's x is level
    EXPECT_LT(R.col(1).dot(up), 0.0);                // image down points downward
    // Looking at a point straight ahead reproduces the forward camera.
    EXPECT_TRUE(camera_looking_at({7, 0, 0}, up).isApprox(camera_looking_forward(), kTolerance));
    EXPECT_THROW(camera_looking_at({0, 0, 5}, up), ConfigError);
    EXPECT_THROW(camera_looking_at({0, 0, 0}, up), ConfigError);
}

TEST(RenderMapView, BadCameraAimsAreClearErrors) {
    EXPECT_THROW(parse_camera_rotation("1,0,0,0,1,0,0,0"), ConfigError);
    EXPECT_THROW(parse_camera_rotation("1,0,0,0,1,0,0,0,-1"), ConfigError);  // a reflection
    EXPECT_THROW(parse_camera_rotation("2,0,0,0,1,0,0,0,1"), ConfigError);
    EXPECT_THROW(parse_point3("1,2", "--camera-look-at"), ConfigError);
    EXPECT_THROW(parse_point3("1,2,x", "--camera-look-at"), ConfigError);
    EXPECT_EQ(parse_point3("1,2.5,-3", "--camera-look-at"), Eigen::Vector3d(1, 2.5, -3));
}

TEST(RenderMapView, BadCameraAndSliceTextsAreClearErrors) {
    EXPECT_THROW(parse_pinhole_camera("500,500,320,240,640"), ConfigError);
    EXPECT_THROW(parse_pinhole_camera("500,0,320,240,640,480"), ConfigError);
    EXPECT_THROW(parse_pinhole_camera("500,500,320,240,640.5,480"), ConfigError);
    EXPECT_THROW(parse_pinhole_camera("a,500,320,240,640,480"), ConfigError);
    EXPECT_THROW(parse_slice_plane("w=1"), ConfigError);
    EXPECT_THROW(parse_slice_plane("z=abc"), ConfigError);
    EXPECT_THROW(parse_slice_plane("z1.5"), ConfigError);
    const SlicePlane p = parse_slice_plane("z=1.5");
    EXPECT_EQ(p.axis, 2);
    EXPECT_EQ(p.value_m, 1.5);
    EXPECT_EQ(p.label(), "z1.50");
    TriangleMesh empty;
    EXPECT_THROW(MeshRenderer{empty}, DataError);
}

TEST(RenderSdfSlice, MatchesDirectQueriesAndIsNanOutsideTheMap) {
    FeatureOctreeConfig octree_config;
    octree_config.leaf_size_m = 0.5;
    NeuralSdf sdf(octree_config, DecoderConfig{});
    sdf.origin_world_m = Eigen::Vector3d(1000.0, 0.0, 0.0);
    // Two separate blobs of cells, so the slice's box holds unobserved pixels between them.
    sdf.octree.allocate_cells({{0.2f, 0.2f, 1.2f}, {4.2f, 3.2f, 1.2f}});
    const ExrImage slice = slice_neural_sdf(sdf, parse_slice_plane("z=1.3"));
    const auto& values = slice.channel("sdf.V");
    const double pixel_m = std::stod(slice.attributes.at("shine_pixel_m"));
    EXPECT_DOUBLE_EQ(pixel_m, 0.5);
    std::size_t finite = 0, unobserved = 0;
    std::vector<Eigen::Vector3f> centres;
    std::istringstream corner(slice.attributes.at("shine_pixel00_world_m"));
    Eigen::Vector3d p00;
    corner >> p00.x() >> p00.y() >> p00.z();
    EXPECT_DOUBLE_EQ(p00.z(), 1.3);
    for (int y = 0; y < slice.height(); ++y) {
        for (int x = 0; x < slice.width(); ++x) {
            const Eigen::Vector3d world = p00 + Eigen::Vector3d(x * pixel_m, -y * pixel_m, 0.0);
            centres.push_back((world - sdf.origin_world_m).cast<float>());
        }
    }
    std::vector<float> expected;
    std::vector<std::uint8_t> valid;
    sdf.query(centres, QueryMask::kLevel0, expected, valid);
    for (std::size_t i = 0; i < values.size(); ++i) {
        if (valid[i]) {
            ++finite;
            EXPECT_EQ(values[i], expected[i]);
        } else {
            ++unobserved;
            EXPECT_TRUE(std::isnan(values[i]));
        }
    }
    EXPECT_GT(finite, 0u);
    EXPECT_GT(unobserved, 0u);
    EXPECT_THROW(slice_neural_sdf(sdf, parse_slice_plane("z=50")), DataError);
}

}  // namespace
}  // namespace shine
