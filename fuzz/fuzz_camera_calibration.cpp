// libFuzzer target: camera calibration (io/camera_rig.hpp). The first byte picks the parser:
// 0 KITTI-360's perspective.txt, 1 its calib_cam_to_velo.txt, 2 the generic layout's camera.yaml;
// the rest is the file. A calibration that is accepted must be usable: finite, positive focal
// lengths, sizes in range, and project() / pixel_ray() callable on it.
#include <cmath>
#include <cstdlib>

#include "fuzz_common.hpp"
#include "shine/io/camera_rig.hpp"

namespace {

void check_camera(const shine::RigCamera& camera) {
    if (camera.width < 1 || camera.height < 1 || camera.width > shine::RgbImage::kMaxSide ||
        camera.height > shine::RgbImage::kMaxSide) {
        std::abort();
    }
    if (!(camera.fx > 0.0) || !(camera.fy > 0.0) || !std::isfinite(camera.fx) ||
        !std::isfinite(camera.fy) || !std::isfinite(camera.cx) || !std::isfinite(camera.cy)) {
        std::abort();
    }
    Eigen::Vector2d uv;
    camera.project(camera.pixel_ray(0.0, 0.0), uv);
    camera.project(camera.T_camera_lidar() * Eigen::Vector3d(10.0, 1.0, -0.5), uv);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    if (size == 0) return 0;
    const std::string_view text = shine_fuzz::as_view(data + 1, size - 1);
    shine_fuzz::expect_value_or_error([&] {
        switch (data[0] % 3) {
            case 0: {
                const shine::Kitti360Rectification rect =
                    shine::parse_kitti360_perspective(text, shine_fuzz::kSource);
                if (!rect.R_rect.allFinite() || !rect.t_rect.allFinite()) std::abort();
                check_camera(shine::kitti360_camera(rect, Eigen::Isometry3d::Identity()));
                break;
            }
            case 1: {
                const Eigen::Isometry3d T_velo_cam =
                    shine::parse_kitti360_cam_to_velo(text, shine_fuzz::kSource);
                if (!T_velo_cam.matrix().allFinite()) std::abort();
                shine::Kitti360Rectification rect;
                rect.width = 1408;
                rect.height = 376;
                rect.fx = rect.fy = 552.554261;
                rect.cx = 682.049453;
                rect.cy = 238.769549;
                check_camera(shine::kitti360_camera(rect, T_velo_cam));
                break;
            }
            default: {
                const shine::RigCamera camera = shine::parse_camera_yaml(text, shine_fuzz::kSource);
                if (!camera.T_lidar_camera.matrix().allFinite()) std::abort();
                check_camera(camera);
            }
        }
    });
    return 0;
}
