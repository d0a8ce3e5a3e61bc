// End to end: `shine render --calibrated-camera` on a hand-made coloured map (needs the `shine`
// executable built). No mapping runs: the map folder holds a mesh.ply of a wall 10 m ahead of the
// LiDAR, its left half (world +y) one colour and its right half another, and the sequence folder
// two scans, their poses and a generic camera rig (docs/cameras.md) of two cameras with the same
// calibration: `front`, whose photo of frame 0 is the wall with every value off by one, and
// `wrong`, whose photo has the halves swapped. Frame 1 has no photos.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <regex>
#include <string>

#include "cli_test_support.hpp"
#include "shine/core/png_image.hpp"
#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/ply.hpp"
#include "shine/render/exr_image.hpp"

namespace shine {
namespace {

using cli_test::CliResult;
using cli_test::run_shine;
namespace fs = std::filesystem;

constexpr Rgb kLeft = {200, 30, 40};   // the wall's half at world y > 0
constexpr Rgb kRight = {20, 180, 60};  // at y < 0
constexpr int kWidth = 64, kHeight = 48;
/// The map lies far from the world origin, as a real drive's would: poses and the mesh's origin.
const Eigen::Vector3d kOriginWorldM(4.0e5, 5.6e6, 120.0);
constexpr double kWallXM = 10.0;  // the wall's distance ahead of frame 0's LiDAR
constexpr double kCameraXM = 0.27, kCameraZM = -0.08;

/// The wall as a mesh in the map's frame: two quads with their own vertices, so the colours do
/// not blend across y = 0.
TriangleMesh wall_mesh(bool rgb, bool intensity) {
    TriangleMesh mesh;
    mesh.origin_world_m = kOriginWorldM;
    for (int half = 0; half < 2; ++half) {
        const float y0 = half == 0 ? 0.0f : -20.0f, y1 = y0 + 20.0f;
        const int base = static_cast<int>(mesh.vertices.size());
        mesh.vertices.emplace_back(kWallXM, y0, -20.0f);
        mesh.vertices.emplace_back(kWallXM, y1, -20.0f);
        mesh.vertices.emplace_back(kWallXM, y1, 20.0f);
        mesh.vertices.emplace_back(kWallXM, y0, 20.0f);
        mesh.triangles.emplace_back(base, base + 1, base + 2);
        mesh.triangles.emplace_back(base, base + 2, base + 3);
        const Rgb c = half == 0 ? kLeft : kRight;
        for (int k = 0; k < 4; ++k) {
            if (rgb) mesh.vertex_rgb.push_back({c.r, c.g, c.b});
            if (intensity) mesh.vertex_intensity.push_back(half == 0 ? 0.2f : 0.4f);
        }
    }
    return mesh;
}

/// Two halves split at column `split` (columns < split are `left`), each value moved by +-1 in
/// a checkerboard when `off_by_one` (a photo whose PSNR against the exact halves is
/// 10 log10(255^2 / 1) = 48.13 dB).
RgbImage halves(int split, Rgb left, Rgb right, bool off_by_one) {
    RgbImage image(kWidth, kHeight);
    for (int v = 0; v < kHeight; ++v) {
        for (int u = 0; u < kWidth; ++u) {
            Rgb c = u < split ? left : right;
            if (off_by_one) {
                const int d = (u + v) % 2 == 0 ? 1 : -1;
                c = {static_cast<std::uint8_t>(c.r + d), static_cast<std::uint8_t>(c.g + d),
                     static_cast<std::uint8_t>(c.b + d)};
            }
            image.set(u, v, c);
        }
    }
    return image;
}

/// The first column of `image` in row `row` that is not `left` (kWidth if none).
int split_column(const RgbImage& image, int row, Rgb left) {
    for (int u = 0; u < kWidth; ++u) {
        if (image.at(u, row) != left) return u;
    }
    return kWidth;
}

double printed_psnr_db(const std::string& output) {
    std::smatch m;
    if (!std::regex_search(output, m, std::regex("PSNR ([0-9.]+) dB"))) return -1.0;
    return std::stod(m[1]);
}

class RenderCalibratedCameraCli : public ::testing::Test {
  protected:
    void SetUp() override {
        if (!fs::exists(SHINE_CLI_PATH)) GTEST_SKIP() << "build the shine target first";
        dir_ = cli_test::test_dir_of("render_camera_cli");
        map_ = dir_ / "map";
        seq_ = dir_ / "seq";
        fs::remove_all(map_);
        fs::remove_all(seq_);
        fs::remove_all(dir_ / "out");
        fs::create_directories(map_);
        write_ply_mesh(map_ / "mesh.ply", wall_mesh(true, false));
        // Two scans (a few points on the wall) at frame 0 and 1 m further on.
        fs::create_directories(seq_ / "velodyne");
        std::vector<Eigen::Isometry3d> poses;
        for (int i = 0; i < 2; ++i) {
            write_kitti_bin(seq_ / "velodyne" / ("00000" + std::to_string(i) + ".bin"),
                            {{10.0f - i, 1.0f, 0.0f}, {10.0f - i, -1.0f, 0.5f}});
            poses.push_back(pose_at(i, 0.0));
        }
        write_kitti_poses(seq_ / "poses.txt", poses);
        for (const char* name : {"front", "wrong"}) {
            const fs::path camera = seq_ / "cameras" / name;
            fs::create_directories(camera);
            std::ofstream(camera / "camera.yaml")
                << "width: 64\nheight: 48\nfx: 32.0\nfy: 32.0\ncx: 31.5\ncy: 23.5\n"
                   "T_lidar_camera: [0, 0, 1, "
                << kCameraXM << ", -1, 0, 0, 0, 0, -1, 0, " << kCameraZM << "]\n";
        }
        halves(32, kLeft, kRight, true).write_png(seq_ / "cameras" / "front" / "000000.png");
        halves(32, kRight, kLeft, false).write_png(seq_ / "cameras" / "wrong" / "000000.png");
    }
    /// The LiDAR of frame i, `y_m` to the left of the wall's colour boundary.
    static Eigen::Isometry3d pose_at(int i, double y_m) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.translation() = kOriginWorldM + Eigen::Vector3d(i, y_m, 0.0);
        return T;
    }
    CliResult render(const std::string& args) const {
        return run_shine("render '" + map_.string() + "' '" + seq_.string() + "' -o '" +
                             (dir_ / "out").string() + "' " + args,
                         dir_);
    }
    fs::path out(const std::string& name) const { return dir_ / "out" / name; }

    fs::path dir_, map_, seq_;
};

TEST_F(RenderCalibratedCameraCli, RendersTheWallsColoursBesideThePhoto) {
    const CliResult r = render("--frame 0 --calibrated-camera");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("poses: the sequence's own"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("camera front (cameras layout, 64 x 48"), std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("pixels with a map surface 100.00 %"), std::string::npos) << r.output;
    // The camera sits on the boundary's line: the left 32 columns show the left half.
    const RgbImage picture = RgbImage::read_png(out("frame_000000_camera.png"));
    ASSERT_EQ(picture.width(), kWidth);
    ASSERT_EQ(picture.height(), kHeight);
    for (int v = 0; v < kHeight; ++v) {
        for (int u = 0; u < kWidth; ++u) {
            ASSERT_EQ(picture.at(u, v), u < 32 ? kLeft : kRight) << u << "," << v;
        }
    }
    // The photo beside it, as read (the +-1 checkerboard), and the PSNR of an error of 1.
    EXPECT_EQ(RgbImage::read_png(out("frame_000000_photo.png")).pixels(),
              halves(32, kLeft, kRight, true).pixels());
    EXPECT_NEAR(printed_psnr_db(r.output), 48.13, 0.01) << r.output;
    // Float layers: the range from the camera's centre at the image centre's pixels, the normal
    // facing back to the camera, linear colours.
    const ExrImage exr = read_exr(out("frame_000000.exr"));
    for (const char* channel :
         {"range.V", "normal.X", "normal.Y", "normal.Z", "color.R", "color.G", "color.B"}) {
        EXPECT_TRUE(exr.has_channel(channel)) << channel;
    }
    EXPECT_FALSE(exr.has_channel("intensity.V"));
    constexpr double kRangeToleranceM = 1e-3;  // 1 mm
    const double depth_m = kWallXM - kCameraXM;
    const double centre_ray_z = 1.0 / std::sqrt(1.0 + 2.0 * std::pow(0.5 / 32.0, 2));
    EXPECT_NEAR(exr.channel("range.V")[23 * kWidth + 31], depth_m / centre_ray_z, kRangeToleranceM);
    EXPECT_NEAR(exr.channel("normal.X")[23 * kWidth + 31], -1.0, 1e-6);
    EXPECT_NEAR(exr.channel("color.R")[0], 0.5776, 1e-4);  // sRGB 200 in linear light
    EXPECT_TRUE(fs::is_regular_file(out("frame_000000_range.png")));
    EXPECT_TRUE(fs::is_regular_file(out("frame_000000_normal.png")));
}

TEST_F(RenderCalibratedCameraCli, AWrongPhotoScoresLow) {
    const CliResult r = render("--frame 0 --calibrated-camera=wrong");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("camera wrong"), std::string::npos) << r.output;
    // Swapped halves: an error of (180, 150, 20) everywhere, 10 log10(255^2 / 18433) = 5.47 dB.
    EXPECT_NEAR(printed_psnr_db(r.output), 5.47, 0.01) << r.output;
}

TEST_F(RenderCalibratedCameraCli, AFrameWithoutAPhotoRendersWithoutComparison) {
    const CliResult r = render("--frame 1 --calibrated-camera");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("no photo " + (seq_ / "cameras" / "front" / "000001.png").string()),
              std::string::npos)
        << r.output;
    EXPECT_EQ(r.output.find("PSNR"), std::string::npos) << r.output;
    EXPECT_TRUE(fs::is_regular_file(out("frame_000001_camera.png")));
    EXPECT_FALSE(fs::exists(out("frame_000001_photo.png")));
}

TEST_F(RenderCalibratedCameraCli, TheMapsRefinedPosesPlaceTheCamera) {
    // The map says frame 0 stood 5 m left of the boundary: seen from there the boundary lies
    // 5 m to the camera's right, at column 31.5 + 32 * 5 / 9.73 = 47.9.
    write_kitti_poses(map_ / "poses_refined.txt", {pose_at(0, 5.0), pose_at(1, 5.0)});
    CliResult r = render("--frame 0 --calibrated-camera");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(
        r.output.find("poses: the map's refined poses, " + (map_ / "poses_refined.txt").string()),
        std::string::npos)
        << r.output;
    EXPECT_EQ(split_column(RgbImage::read_png(out("frame_000000_camera.png")), 20, kLeft), 48);
    EXPECT_LT(printed_psnr_db(r.output), 20.0) << r.output;
    // --poses overrides them.
    r = render("--frame 0 --calibrated-camera --poses '" + (seq_ / "poses.txt").string() + "'");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("poses: --poses"), std::string::npos) << r.output;
    EXPECT_EQ(split_column(RgbImage::read_png(out("frame_000000_camera.png")), 20, kLeft), 32);
    // Refined poses of another selection of scans are named, not used.
    fs::remove_all(dir_ / "out");
    write_kitti_poses(map_ / "poses_refined.txt", {pose_at(0, 5.0)});
    r = render("--frame 0 --calibrated-camera");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("poses_refined.txt' holds 1 poses but"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir_ / "out"));
}

TEST_F(RenderCalibratedCameraCli, WithoutColoursIntensityOrShadingIsGrey) {
    write_ply_mesh(map_ / "mesh.ply", wall_mesh(false, true));
    CliResult r = render("--frame 0 --calibrated-camera");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("LiDAR intensity shown as grey"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("no PSNR"), std::string::npos) << r.output;
    RgbImage picture = RgbImage::read_png(out("frame_000000_camera.png"));
    EXPECT_EQ(picture.at(5, 20), (Rgb{128, 128, 128}));  // 0.2 of the white point 0.4
    EXPECT_EQ(picture.at(60, 20), (Rgb{255, 255, 255}));
    EXPECT_TRUE(read_exr(out("frame_000000.exr")).has_channel("intensity.V"));

    write_ply_mesh(map_ / "mesh.ply", wall_mesh(false, false));
    r = render("--frame 0 --calibrated-camera");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("shaded grey"), std::string::npos) << r.output;
    picture = RgbImage::read_png(out("frame_000000_camera.png"));
    EXPECT_EQ(picture.at(31, 23), (Rgb{255, 255, 255}));  // head-on
}

TEST_F(RenderCalibratedCameraCli, ErrorsNameTheFolderTheCameraAndTheFrame) {
    // A sequence without cameras: the folder, the layouts and the page.
    fs::remove_all(seq_ / "cameras");
    CliResult r = render("--frame 0 --calibrated-camera");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("'" + seq_.string() + "' has no cameras"), std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("cameras/<name>/camera.yaml"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("image_00/"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("docs/cameras.md"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir_ / "out"));
    SetUp();
    // An unknown camera: the names there are.
    r = render("--frame 0 --calibrated-camera=back");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("--calibrated-camera back"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("has front, wrong"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir_ / "out"));
    // A frame out of range.
    r = render("--frame 2 --calibrated-camera");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("--frame 2 is outside the sequence"), std::string::npos) << r.output;
    // A photo of the wrong size names its file.
    RgbImage(32, 24).write_png(seq_ / "cameras" / "front" / "000000.png");
    r = render("--frame 0 --calibrated-camera");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("000000.png"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(dir_ / "out"));
    // Calibrated and pinhole cameras at once.
    r = render("--frame 0 --calibrated-camera --camera 10,10,5,5,10,10");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("excludes"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace shine
