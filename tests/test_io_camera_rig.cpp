// Camera rigs of sequence folders (io/camera_rig.hpp): KITTI-360's calibration checked against
// its own projection formula on the real files' numbers, the generic camera.yaml layout, and
// every broken calibration naming its file.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/core/png_image.hpp"
#include "shine/io/camera_rig.hpp"

namespace fs = std::filesystem;
using namespace shine;

namespace {

// KITTI-360's calibration/perspective.txt and calib_cam_to_velo.txt, copied unchanged from
// /work/shared/data/kitti360_drive/calibration/.
const char* const kPerspective = R"(calib_time: 17-Feb-2016 14:23:48
corner_dist: 0.100000
S_00: 1392.000000 512.000000
K_00: 788.629315 0.000000 687.158398 0.000000 786.382230 317.752196 0.000000 0.000000 0.000000
D_00: -0.344441 0.141678 0.000414 -0.000222 -0.029608
R_00: 1.000000 0.000000 0.000000 0.000000 1.000000 0.000000 0.000000 0.000000 1.000000
T_00: 0.000000 0.000000 0.000000
S_rect_00: 1408.000000 376.000000
R_rect_00: 0.999974 -0.007141 -0.000089 0.007141 0.999969 -0.003247 0.000112 0.003247 0.999995
P_rect_00: 552.554261 0.000000 682.049453 0.000000 0.000000 552.554261 238.769549 0.000000 0.000000 0.000000 1.000000 0.000000
S_01: 1392.000000 512.000000
K_01: 785.134093 0.000000 686.437073 0.000000 782.346289 321.352788 0.000000 0.000000 0.000000
D_01: -0.353195 0.161996 0.000383 -0.000242 -0.041476
R_01: 0.999837 0.004862 -0.017390 -0.004974 0.999967 -0.006389 0.017358 0.006474 0.999828
T_01: -0.594052 0.007198 -0.010233
S_rect_01: 1408.000000 376.000000
R_rect_01: 0.999778 -0.012115 0.017222 0.012059 0.999922 0.003351 -0.017261 -0.003143 0.999846
P_rect_01: 552.554261 0.000000 682.049453 -328.318735 0.000000 552.554261 238.769549 0.000000 0.000000 0.000000 1.000000 0.000000
)";
const char* const kCamToVelo =
    "0.04307104361 -0.08829286498 0.995162929 0.8043914418 -0.999004371 0.007784614041 "
    "0.04392796942 0.2993489574 -0.01162548558 -0.9960641394 -0.08786966659 -0.1770225824\n";

constexpr double kPixelTolerance = 1e-6;  // px: the same formula, only rounding apart

const char* const kCameraYaml = R"(width: 640          # pixels
height: 240
fx: 320.0           # pixels, rectified pinhole, no distortion
fy: 310.0
cx: 319.5           # pixel centres at integer coordinates
cy: 119.5
T_lidar_camera: [0, 0, 1, 0.5,  -1, 0, 0, 0.1,  0, -1, 0, 1.2]
)";

fs::path test_dir(const std::string& name) {
    const fs::path dir = fs::path(SHINE_TEST_TMP_DIR) / "io_camera_rig" / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

void write_text(const fs::path& path, const std::string& text) {
    fs::create_directories(path.parent_path());
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << text;
    ASSERT_TRUE(out.good()) << path;
}

/// A KITTI-360 sequence folder: velodyne/ with empty scans 000002 and 000003, image_00/ with
/// 000003.png only, and calibration/.
fs::path kitti360_dir(const std::string& name, const std::string& perspective = kPerspective,
                      const std::string& cam_to_velo = kCamToVelo) {
    const fs::path dir = test_dir(name);
    for (const char* stem : {"000002", "000003"}) {
        write_text(dir / "velodyne" / (std::string(stem) + ".bin"), "");
    }
    fs::create_directories(dir / "image_00");
    // A stand-in of 1 x 1 pixels keeps the error cases fast; the layout test writes a full one.
    RgbImage(1, 1).write_png(dir / "image_00" / "000003.png");
    write_text(dir / "calibration" / "perspective.txt", perspective);
    write_text(dir / "calibration" / "calib_cam_to_velo.txt", cam_to_velo);
    return dir;
}

/// `text` with the line starting with `key` replaced by `line` (or removed when empty).
std::string replace_line(const std::string& text, const std::string& key, const std::string& line) {
    const std::size_t start = text.find("\n" + key) + 1;
    const std::size_t end = text.find('\n', start) + 1;
    return text.substr(0, start) + (line.empty() ? "" : line + "\n") + text.substr(end);
}

/// Runs `f` and checks that it throws E whose message contains every fragment.
template <typename E, typename F>
void expect_error(F&& f, const std::vector<std::string>& fragments) {
    try {
        f();
        ADD_FAILURE() << "expected an error mentioning " << fragments.front();
    } catch (const E& e) {
        const std::string message = e.what();
        for (const std::string& fragment : fragments) {
            EXPECT_NE(message.find(fragment), std::string::npos)
                << "missing '" << fragment << "' in: " << message;
        }
    } catch (const std::exception& e) {
        ADD_FAILURE() << "wrong exception type: " << e.what();
    }
}

/// KITTI-360's formula, written out: [u w, v w, w] = P_rect_00 R_rect_00 T_cam_to_velo^-1 [p, 1].
Eigen::Vector3d kitti360_raw_projection(const Eigen::Vector3d& p_lidar) {
    Eigen::Matrix<double, 3, 4> P;
    P << 552.554261, 0.000000, 682.049453, 0.000000,  //
        0.000000, 552.554261, 238.769549, 0.000000,   //
        0.000000, 0.000000, 1.000000, 0.000000;
    Eigen::Matrix4d R_rect = Eigen::Matrix4d::Identity();
    R_rect.topLeftCorner<3, 3>() << 0.999974, -0.007141, -0.000089,  //
        0.007141, 0.999969, -0.003247,                               //
        0.000112, 0.003247, 0.999995;
    Eigen::Matrix4d T_cam_to_velo = Eigen::Matrix4d::Identity();
    T_cam_to_velo.topRows<3>() << 0.04307104361, -0.08829286498, 0.995162929, 0.8043914418,
        -0.999004371, 0.007784614041, 0.04392796942, 0.2993489574, -0.01162548558, -0.9960641394,
        -0.08786966659, -0.1770225824;
    return P * R_rect * T_cam_to_velo.inverse() * p_lidar.homogeneous();
}

const std::vector<Eigen::Vector3d> kPointsAhead = {{10.0, 1.0, -0.5}, {20.0, -3.0, 1.0},
                                                   {6.0, 2.0, -1.2},  {45.0, 8.0, 3.0},
                                                   {5.0, 0.0, -1.2},  {8.0, -2.0, -1.5}};

}  // namespace

TEST(CameraRig, Kitti360ProjectionIsTheCalibrationFilesFormula) {
    const RigCamera camera = kitti360_camera(parse_kitti360_perspective(kPerspective, "p.txt"),
                                             parse_kitti360_cam_to_velo(kCamToVelo, "c.txt"));
    EXPECT_EQ(camera.name, "image_00");
    EXPECT_EQ(camera.width, 1408);
    EXPECT_EQ(camera.height, 376);
    EXPECT_EQ(camera.fx, 552.554261);
    EXPECT_EQ(camera.fy, 552.554261);
    EXPECT_EQ(camera.cx, 682.049453);
    EXPECT_EQ(camera.cy, 238.769549);
    for (const Eigen::Vector3d& p : kPointsAhead) {
        const Eigen::Vector3d uvw = kitti360_raw_projection(p);
        ASSERT_GT(uvw.z(), 0.0);
        const Eigen::Vector2d expected = uvw.hnormalized();
        Eigen::Vector2d uv;
        ASSERT_TRUE(camera.project(camera.T_camera_lidar() * p, uv)) << p.transpose();
        EXPECT_NEAR(uv.x(), expected.x(), kPixelTolerance) << p.transpose();
        EXPECT_NEAR(uv.y(), expected.y(), kPixelTolerance) << p.transpose();
        // Isometry3d::inverse() takes R_rect_00 (6 decimals) as exactly orthonormal: close, not
        // exact (docs/cameras.md quotes the bound).
        Eigen::Vector2d uv_isometric;
        ASSERT_TRUE(camera.project(camera.T_lidar_camera.inverse() * p, uv_isometric));
        EXPECT_NEAR(uv_isometric.x(), expected.x(), 1e-2);
        EXPECT_NEAR(uv_isometric.y(), expected.y(), 1e-2);
        // The pixel's ray passes through the point.
        const Eigen::Vector3d ray = camera.pixel_ray(uv.x(), uv.y());
        EXPECT_NEAR(ray.norm(), 1.0, 1e-12);
        EXPECT_LT(ray.cross((camera.T_camera_lidar() * p).normalized()).norm(), 1e-9);
    }
    // Behind the car (the camera looks forward, along the LiDAR's x).
    Eigen::Vector2d uv(-7.0, -7.0);
    EXPECT_FALSE(camera.project(camera.T_camera_lidar() * Eigen::Vector3d(-10.0, 0.0, 0.0), uv));
    EXPECT_EQ(uv, Eigen::Vector2d(-7.0, -7.0)) << "left unchanged";
    // Ahead but far to the side: outside the image.
    EXPECT_FALSE(camera.project(camera.T_camera_lidar() * Eigen::Vector3d(1.0, 30.0, 0.0), uv));
}

TEST(CameraRig, Kitti360CameraOtherThanZeroHasItsBaselineInTheTranslation) {
    // P_rect with a 4th column: t' = K^-1 P[:, 3] shifts the optical frame (image_01's baseline).
    const std::string perspective =
        replace_line(kPerspective, "P_rect_00",
                     "P_rect_00: 552.554261 0.000000 682.049453 -328.318735 0.000000 552.554261 "
                     "238.769549 0.000000 0.000000 0.000000 1.000000 0.000000");
    const Kitti360Rectification rect = parse_kitti360_perspective(perspective, "p.txt");
    EXPECT_NEAR(rect.t_rect.x(), -328.318735 / 552.554261, 1e-12);
    EXPECT_EQ(rect.t_rect.y(), 0.0);
    const RigCamera camera = kitti360_camera(rect, parse_kitti360_cam_to_velo(kCamToVelo, "c"));
    Eigen::Matrix<double, 3, 4> P;
    P << 552.554261, 0, 682.049453, -328.318735, 0, 552.554261, 238.769549, 0, 0, 0, 1, 0;
    const Eigen::Vector3d p(12.0, -1.0, 0.5);
    Eigen::Vector2d uv;
    ASSERT_TRUE(camera.project(camera.T_camera_lidar() * p, uv));
    Eigen::Matrix4d R = Eigen::Matrix4d::Identity();
    R.topLeftCorner<3, 3>() = rect.R_rect;
    Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
    T.topRows<3>() = parse_kitti360_cam_to_velo(kCamToVelo, "c").matrix().topRows<3>();
    const Eigen::Vector2d expected = (P * R * T.inverse() * p.homogeneous()).hnormalized();
    EXPECT_NEAR((uv - expected).norm(), 0.0, kPixelTolerance);
}

TEST(CameraRig, FindsTheKitti360LayoutAndItsImages) {
    const fs::path dir = kitti360_dir("kitti360");
    RgbImage(1408, 376, {10, 20, 30}).write_png(dir / "image_00" / "000003.png");
    const auto rig = find_camera_rig(dir);
    ASSERT_TRUE(rig.has_value());
    EXPECT_EQ(rig->layout, "kitti360");
    ASSERT_EQ(rig->cameras.size(), 1u);
    const RigCamera& camera = rig->cameras[0];
    EXPECT_EQ(camera.image_dir, dir / "image_00");
    EXPECT_EQ(camera.calibration_path, dir / "calibration" / "perspective.txt");
    for (const Eigen::Vector3d& p : kPointsAhead) {
        Eigen::Vector2d uv;
        ASSERT_TRUE(camera.project(camera.T_camera_lidar() * p, uv));
        EXPECT_NEAR((uv - kitti360_raw_projection(p).hnormalized()).norm(), 0.0, kPixelTolerance);
    }
    EXPECT_EQ(rig->image_for_scan(0, dir / "velodyne" / "000003.bin"),
              dir / "image_00" / "000003.png");
    EXPECT_TRUE(rig->image_for_scan(0, dir / "velodyne" / "000002.bin").empty());
    EXPECT_THROW(rig->image_for_scan(1, dir / "velodyne" / "000003.bin"), std::out_of_range);
    const RgbImage image = load_camera_image(camera, dir / "image_00" / "000003.png");
    EXPECT_EQ(image.at(700, 200), (Rgb{10, 20, 30}));
}

TEST(CameraRig, RealKitti360Drive) {
    const fs::path dir = "/work/shared/data/kitti360_drive";
    if (!fs::exists(dir / "image_00")) GTEST_SKIP() << dir << " is not on this machine";
    const auto rig = find_camera_rig(dir);
    ASSERT_TRUE(rig.has_value());
    const RigCamera& camera = rig->cameras.at(0);
    for (const Eigen::Vector3d& p : kPointsAhead) {
        Eigen::Vector2d uv;
        ASSERT_TRUE(camera.project(camera.T_camera_lidar() * p, uv));
        EXPECT_NEAR((uv - kitti360_raw_projection(p).hnormalized()).norm(), 0.0, kPixelTolerance);
    }
    const fs::path image = rig->image_for_scan(0, dir / "velodyne" / "000003.bin");
    ASSERT_EQ(image, dir / "image_00" / "000003.png");
    EXPECT_EQ(load_camera_image(camera, image).width(), 1408);
}

TEST(CameraRig, GenericLayoutWithCamerasSortedByName) {
    const fs::path dir = test_dir("generic");
    write_text(dir / "cameras" / "front" / "camera.yaml", kCameraYaml);
    // The same pose as a 4x4 matrix, for a second camera.
    write_text(dir / "cameras" / "back" / "camera.yaml",
               "width: 32\nheight: 16\nfx: 20\nfy: 20\ncx: 15.5\ncy: 7.5\n"
               "T_lidar_camera: [0, 0, 1, 0.5, -1, 0, 0, 0.1, 0, -1, 0, 1.2, 0, 0, 0, 1]\n");
    write_text(dir / "cameras" / "README.txt", "not a camera");  // files are ignored
    RgbImage(640, 240).write_png(dir / "cameras" / "front" / "000003.png");

    const auto rig = find_camera_rig(dir);
    ASSERT_TRUE(rig.has_value());
    EXPECT_EQ(rig->layout, "cameras");
    ASSERT_EQ(rig->cameras.size(), 2u);
    EXPECT_EQ(rig->cameras[0].name, "back");
    const RigCamera& front = rig->cameras[1];
    EXPECT_EQ(front.name, "front");
    EXPECT_EQ(front.width, 640);
    EXPECT_EQ(front.height, 240);
    EXPECT_EQ(front.fx, 320.0);
    EXPECT_EQ(front.fy, 310.0);
    EXPECT_EQ(front.cx, 319.5);
    EXPECT_EQ(front.cy, 119.5);
    EXPECT_EQ(front.calibration_path, dir / "cameras" / "front" / "camera.yaml");
    EXPECT_EQ(front.image_dir, dir / "cameras" / "front");
    EXPECT_TRUE(rig->cameras[0].T_lidar_camera.isApprox(front.T_lidar_camera, 0.0));

    // The optical axis looks along the LiDAR's x: a point 4 m ahead of the camera is the centre.
    const Eigen::Vector3d p_lidar = Eigen::Vector3d(0.5, 0.1, 1.2) + Eigen::Vector3d(4, 0, 0);
    Eigen::Vector2d uv;
    ASSERT_TRUE(front.project(front.T_camera_lidar() * p_lidar, uv));
    EXPECT_NEAR(uv.x(), 319.5, 1e-9);
    EXPECT_NEAR(uv.y(), 119.5, 1e-9);
    // The camera's y is down: a point above (LiDAR z up) is on a row above the centre.
    ASSERT_TRUE(front.project(front.T_camera_lidar() * (p_lidar + Eigen::Vector3d(0, 0, 1)), uv));
    EXPECT_NEAR(uv.y(), 119.5 - 310.0 / 4.0, 1e-9);

    EXPECT_EQ(rig->image_for_scan(1, "/elsewhere/velodyne/000003.bin"),
              dir / "cameras" / "front" / "000003.png");
    EXPECT_TRUE(rig->image_for_scan(0, "/elsewhere/velodyne/000003.bin").empty());
    EXPECT_TRUE(rig->image_for_scan(1, "000004.ply").empty());
    EXPECT_EQ(load_camera_image(front, dir / "cameras" / "front" / "000003.png").width(), 640);
}

TEST(CameraRig, ProjectKeepsPixelCentresAndEdges) {
    RigCamera camera = parse_camera_yaml(kCameraYaml, "camera.yaml");
    Eigen::Vector2d uv;
    // The image spans [-0.5, width - 0.5) x [-0.5, height - 0.5).
    EXPECT_TRUE(camera.project(camera.pixel_ray(-0.5, -0.5), uv));
    EXPECT_NEAR(uv.x(), -0.5, 1e-12);
    EXPECT_FALSE(camera.project(camera.pixel_ray(-0.5 - 1e-6, 10.0), uv));
    EXPECT_FALSE(camera.project(camera.pixel_ray(639.5, 10.0), uv));
    EXPECT_TRUE(camera.project(camera.pixel_ray(639.4999, 239.4999), uv));
    EXPECT_FALSE(camera.project(camera.pixel_ray(10.0, 239.5), uv));
    EXPECT_FALSE(camera.project(Eigen::Vector3d(0, 0, 0), uv));
    EXPECT_FALSE(camera.project(Eigen::Vector3d(0, 0, -1), uv));
    EXPECT_FALSE(camera.project(Eigen::Vector3d(NAN, 0, 1), uv));
    for (const auto& [u, v] : {std::pair{0.0, 0.0}, {123.25, 45.5}, {639.0, 239.0}}) {
        ASSERT_TRUE(camera.project(3.7 * camera.pixel_ray(u, v), uv));
        EXPECT_NEAR(uv.x(), u, 1e-9);
        EXPECT_NEAR(uv.y(), v, 1e-9);
    }
}

TEST(CameraRig, SequenceWithoutImagesHasNoRig) {
    const fs::path dir = test_dir("no_images");
    write_text(dir / "velodyne" / "000000.bin", "");
    write_text(dir / "poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n");
    EXPECT_FALSE(find_camera_rig(dir).has_value());
    EXPECT_FALSE(find_camera_rig(dir / "poses.txt").has_value()) << "a file, like a recording";
    EXPECT_FALSE(find_camera_rig(dir / "missing").has_value());
}

TEST(CameraRig, Kitti360CalibrationErrorsNameTheFile) {
    {
        const fs::path dir = kitti360_dir("no_perspective");
        fs::remove(dir / "calibration" / "perspective.txt");
        expect_error<IoError>([&] { find_camera_rig(dir); },
                              {"perspective.txt", "image_00/", "copy KITTI-360's calibration/"});
    }
    {
        const fs::path dir = kitti360_dir("no_cam_to_velo");
        fs::remove(dir / "calibration" / "calib_cam_to_velo.txt");
        expect_error<IoError>([&] { find_camera_rig(dir); }, {"calib_cam_to_velo.txt"});
    }
    const std::string file = "perspective.txt";
    const auto expect_perspective_error = [&](const std::string& name, const std::string& text,
                                              const std::vector<std::string>& fragments) {
        const fs::path dir = kitti360_dir(name, text);
        std::vector<std::string> all = fragments;
        all.push_back((dir / "calibration" / "perspective.txt").string());
        expect_error<IoError>([&] { find_camera_rig(dir); }, all);
    };
    expect_perspective_error("missing_key", replace_line(kPerspective, "R_rect_00", ""),
                             {"no R_rect_00 line", "9 numbers"});
    expect_perspective_error("missing_size", replace_line(kPerspective, "S_rect_00", ""),
                             {"no S_rect_00 line"});
    expect_perspective_error(
        "non_number",
        replace_line(kPerspective, "P_rect_00",
                     "P_rect_00: 552.554261 0.000000 682.04x453 0.000000 0.000000 552.554261 "
                     "238.769549 0.000000 0.000000 0.000000 1.000000 0.000000"),
        {"line 10 (P_rect_00)", "'682.04x453' is not a number"});
    expect_perspective_error("wrong_count",
                             replace_line(kPerspective, "R_rect_00", "R_rect_00: 1 0 0 0 1 0 0 0"),
                             {"R_rect_00", "expected 9 numbers", "found 8"});
    expect_perspective_error(
        "non_rotation", replace_line(kPerspective, "R_rect_00", "R_rect_00: 2 0 0 0 2 0 0 0 2"),
        {"R_rect_00 is not a rotation"});
    expect_perspective_error(
        "reflection", replace_line(kPerspective, "R_rect_00", "R_rect_00: -1 0 0 0 1 0 0 0 1"),
        {"R_rect_00 is not a rotation", "det(R) = -1"});
    expect_perspective_error("repeated", std::string(kPerspective) + "S_rect_00: 10 10\n",
                             {"repeats the key of line 8"});
    expect_perspective_error("bad_size",
                             replace_line(kPerspective, "S_rect_00", "S_rect_00: 1408.5 376"),
                             {"S_rect_00 = 1408.5 376 is not an image size"});
    expect_perspective_error(
        "not_pinhole",
        replace_line(kPerspective, "P_rect_00",
                     "P_rect_00: 552.554261 3.0 682.049453 0.000000 0.000000 552.554261 "
                     "238.769549 0.000000 0.000000 0.000000 1.000000 0.000000"),
        {"not a rectified pinhole camera matrix"});
    expect_perspective_error(
        "non_finite", replace_line(kPerspective, "R_rect_00", "R_rect_00: 1 0 0 0 1 0 0 0 nan"),
        {"non-finite"});

    const auto expect_cam_to_velo_error = [&](const std::string& name, const std::string& text,
                                              const std::vector<std::string>& fragments) {
        const fs::path dir = kitti360_dir(name, kPerspective, text);
        std::vector<std::string> all = fragments;
        all.push_back((dir / "calibration" / "calib_cam_to_velo.txt").string());
        expect_error<IoError>([&] { find_camera_rig(dir); }, all);
    };
    expect_cam_to_velo_error("velo_count", "1 0 0 0 0 1 0 0 0 0 1\n",
                             {"holds 11 numbers", "expected 12 numbers"});
    expect_cam_to_velo_error("velo_non_number", "1 0 0 0 0 1 0 0 0 0 1 zero\n",
                             {"'zero' is not a number"});
    expect_cam_to_velo_error("velo_non_rotation", "1 0 0 0 0 1 0 0 0 1 1 0\n",
                             {"is not a rotation"});
    expect_cam_to_velo_error("velo_empty", "", {"empty"});
}

TEST(CameraRig, CameraYamlErrorsNameTheFileAndKey) {
    const auto expect_yaml_error = [](const std::string& name, const std::string& text,
                                      const std::vector<std::string>& fragments) {
        const fs::path dir = test_dir("yaml_" + name);
        const fs::path yaml = dir / "cameras" / "cam" / "camera.yaml";
        write_text(yaml, text);
        std::vector<std::string> all = fragments;
        all.push_back(yaml.string());
        expect_error<ConfigError>([&] { find_camera_rig(dir); }, all);
    };
    const std::string yaml = kCameraYaml;
    const auto with = [&](const std::string& key, const std::string& line) {
        return replace_line("\n" + yaml, key, line).substr(1);
    };
    expect_yaml_error("unknown_key", yaml + "k1: 0.1\n", {"unknown key 'k1'", "known: width"});
    expect_yaml_error("missing_key", with("fy", ""), {"missing key 'fy'"});
    expect_yaml_error("non_number", with("fx", "fx: wide"), {"fx = 'wide' is not a number"});
    expect_yaml_error("zero_focal", with("fy", "fy: 0"), {"fy = 0 is not a focal length"});
    expect_yaml_error("nan", with("cx", "cx: .nan"), {"cx is not finite"});
    expect_yaml_error("size_zero", with("width", "width: 0"), {"width = 0 is not"});
    expect_yaml_error("size_large", with("height", "height: 40000"), {"height = 40000 is not"});
    expect_yaml_error("size_fraction", with("width", "width: 640.5"), {"width = 640.5 is not"});
    expect_yaml_error("wrong_count",
                      with("T_lidar_camera", "T_lidar_camera: [1, 0, 0, 0, 1, 0, 0, 0, 1]"),
                      {"T_lidar_camera has 9 numbers", "12 (3x4) or 16"});
    expect_yaml_error("not_a_list", with("T_lidar_camera", "T_lidar_camera: 1"),
                      {"T_lidar_camera is not a list"});
    expect_yaml_error(
        "non_rotation",
        with("T_lidar_camera", "T_lidar_camera: [1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1, 0]"),
        {"T_lidar_camera's left 3x3 R is not a rotation"});
    expect_yaml_error(
        "reflection",
        with("T_lidar_camera", "T_lidar_camera: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -1, 0]"),
        {"is not a rotation", "det(R) = -1"});
    expect_yaml_error(
        "last_row",
        with("T_lidar_camera", "T_lidar_camera: [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1]"),
        {"last row is 0 0 1 1"});
    expect_yaml_error(
        "entry_non_number",
        with("T_lidar_camera", "T_lidar_camera: [1, 0, 0, 0, 0, 1, 0, x, 0, 0, 1, 0]"),
        {"T_lidar_camera[7] = 'x' is not a number"});
    expect_yaml_error("repeated", yaml + "fx: 300\n", {"fx"});
    expect_yaml_error("syntax", "width: [640\n", {"is not valid YAML"});
    expect_yaml_error("not_a_map", "- 640\n- 240\n", {"expected a mapping"});
}

TEST(CameraRig, GenericLayoutErrorsNameTheFolder) {
    {
        const fs::path dir = test_dir("no_yaml");
        fs::create_directories(dir / "cameras" / "left");
        expect_error<IoError>([&] { find_camera_rig(dir); },
                              {(dir / "cameras" / "left" / "camera.yaml").string(), "write one"});
    }
    {
        const fs::path dir = test_dir("empty_cameras");
        fs::create_directories(dir / "cameras");
        expect_error<IoError>([&] { find_camera_rig(dir); },
                              {(dir / "cameras").string(), "holds no camera"});
    }
    {
        const fs::path dir = kitti360_dir("both_layouts");
        write_text(dir / "cameras" / "cam" / "camera.yaml", kCameraYaml);
        expect_error<DataError>([&] { find_camera_rig(dir); }, {dir.string(), "keep one layout"});
    }
}

TEST(CameraRig, ImageOfTheWrongSizeNamesTheFile) {
    const fs::path dir = test_dir("wrong_size");
    write_text(dir / "cameras" / "cam" / "camera.yaml", kCameraYaml);
    const fs::path image = dir / "cameras" / "cam" / "000000.png";
    RgbImage(320, 240).write_png(image);
    const auto rig = find_camera_rig(dir);
    ASSERT_TRUE(rig.has_value());
    expect_error<DataError>([&] { load_camera_image(rig->cameras[0], image); },
                            {image.string(), "320 x 240", "640 x 240", "camera.yaml"});
    write_text(image, "not a png");
    expect_error<IoError>([&] { load_camera_image(rig->cameras[0], image); },
                          {image.string(), "not a PNG"});
}
