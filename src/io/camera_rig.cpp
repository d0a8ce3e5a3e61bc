// The cameras of a sequence folder: KITTI-360's calibration files and the generic camera.yaml.
#include "shine/io/camera_rig.hpp"

#include <yaml-cpp/yaml.h>

#include <Eigen/LU>
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <set>
#include <stdexcept>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/io/file_contents.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace camera_rig_internal {
namespace {

// KITTI-360 stores rotations with 6 decimals (about 1e-6 from orthonormal); 1e-3 still catches
// a transposed, scaled or garbled matrix.
constexpr double kOrthonormalTolerance = 1e-3;
// The last row of a 4x4 T_lidar_camera, and P_rect_00's zeros, are exact in any file we accept.
constexpr double kExactTolerance = 1e-9;

std::string number_text(double v) {
    char text[32];
    std::snprintf(text, sizeof(text), "%.9g", v);
    return text;
}

/// Why `R` is not a rotation (orthonormal within kOrthonormalTolerance, determinant > 0), or "".
std::string rotation_problem(const Eigen::Matrix3d& R) {
    const double error = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
    const double det = R.determinant();
    if (error <= kOrthonormalTolerance && det > 0.0) return "";
    return "is not a rotation (max |R^T R - I| = " + number_text(error) +
           ", det(R) = " + number_text(det) + "; expected orthonormal within 1e-3, det +1)";
}

/// An integral pixel count in [1, RgbImage::kMaxSide], or -1.
int side_in_pixels(double v) {
    if (!(v >= 1.0 && v <= RgbImage::kMaxSide) || v != std::floor(v)) return -1;
    return static_cast<int>(v);
}

// --- KITTI-360 ----------------------------------------------------------------------------------

[[noreturn]] void fail_kitti360(const fs::path& source, const std::string& what) {
    throw IoError("KITTI-360 calibration '" + source.string() + "': " + what);
}

/// The numbers of line `KEY: ...` of perspective.txt; exactly `count` of them, all finite.
std::vector<double> kitti360_key(std::string_view text, const fs::path& source,
                                 const std::string& key, std::size_t count,
                                 const std::string& meaning) {
    std::vector<double> values;
    int found_line = 0;
    int line_number = 0;
    std::size_t begin = 0;
    while (begin < text.size()) {
        std::size_t end = text.find('\n', begin);
        if (end == std::string_view::npos) end = text.size();
        const std::string_view line = text.substr(begin, end - begin);
        begin = end + 1;
        ++line_number;
        const std::size_t colon = line.find(':');
        if (colon == std::string_view::npos) continue;
        std::string_view name = line.substr(0, colon);
        while (!name.empty() && std::isspace(static_cast<unsigned char>(name.front()))) {
            name.remove_prefix(1);
        }
        while (!name.empty() && std::isspace(static_cast<unsigned char>(name.back()))) {
            name.remove_suffix(1);
        }
        if (name != key) continue;
        const std::string where = "line " + std::to_string(line_number) + " (" + key + ")";
        if (found_line != 0) {
            fail_kitti360(source, where + " repeats the key of line " + std::to_string(found_line) +
                                      "; keep one " + key + " line");
        }
        found_line = line_number;
        std::string bad;
        if (!parse_number_words(line.substr(colon + 1), &values, &bad)) {
            fail_kitti360(source, where + ": '" + bad + "' is not a number; expected " +
                                      std::to_string(count) + " numbers, " + meaning);
        }
        if (values.size() != count) {
            fail_kitti360(source, where + ": expected " + std::to_string(count) + " numbers (" +
                                      meaning + "), found " + std::to_string(values.size()));
        }
        for (double v : values) {
            if (!std::isfinite(v)) fail_kitti360(source, where + " holds a non-finite value");
        }
    }
    if (found_line == 0) {
        fail_kitti360(source, "no " + key + " line; expected '" + key + ": ' followed by " +
                                  std::to_string(count) + " numbers (" + meaning +
                                  "), as KITTI-360's calibration/perspective.txt has");
    }
    return values;
}

// --- camera.yaml --------------------------------------------------------------------------------

[[noreturn]] void fail_yaml(const fs::path& source, const std::string& what) {
    throw ConfigError("camera calibration '" + source.string() + "': " + what);
}

const char* const kCameraYamlKeys[] = {"width", "height", "fx", "fy", "cx", "cy", "T_lidar_camera"};

double yaml_number(const YAML::Node& node, const fs::path& source, const std::string& key,
                   const std::string& expected) {
    double v = 0.0;
    bool ok = node.IsScalar();
    if (ok) {
        try {
            v = node.as<double>();
        } catch (const YAML::Exception&) {
            ok = false;
        }
    }
    if (!ok) {
        fail_yaml(source, key + " = '" + (node.IsScalar() ? printable_excerpt(node.Scalar()) : "") +
                              "' is not a number; expected " + expected);
    }
    if (!std::isfinite(v)) fail_yaml(source, key + " is not finite; expected " + expected);
    return v;
}

}  // namespace
}  // namespace camera_rig_internal

bool RigCamera::project(const Eigen::Vector3d& p_camera, Eigen::Vector2d& pixel_uv) const {
    if (!(p_camera.z() > 0.0)) return false;
    const double u = fx * p_camera.x() / p_camera.z() + cx;
    const double v = fy * p_camera.y() / p_camera.z() + cy;
    // Written so that NaN fails every comparison and the point is rejected.
    if (!(u >= -0.5 && u < width - 0.5 && v >= -0.5 && v < height - 0.5)) return false;
    pixel_uv = {u, v};
    return true;
}

Eigen::Vector3d RigCamera::pixel_ray(double u, double v) const {
    return Eigen::Vector3d((u - cx) / fx, (v - cy) / fy, 1.0).normalized();
}

Eigen::Isometry3d RigCamera::T_camera_lidar() const {
    Eigen::Isometry3d T;
    T.matrix() = T_lidar_camera.matrix().inverse();
    return T;
}

fs::path CameraRig::image_for_scan(std::size_t camera, const fs::path& scan_path) const {
    if (camera >= cameras.size()) {
        throw std::out_of_range("camera " + std::to_string(camera) + " of a rig with " +
                                std::to_string(cameras.size()) + " cameras");
    }
    fs::path image = cameras[camera].image_dir / scan_path.stem();
    image += ".png";
    std::error_code ec;
    if (!fs::is_regular_file(image, ec)) return {};
    return image;
}

Kitti360Rectification parse_kitti360_perspective(std::string_view text, const fs::path& source) {
    using namespace camera_rig_internal;
    const std::vector<double> S = kitti360_key(text, source, "S_rect_00", 2, "width height");
    const std::vector<double> R = kitti360_key(text, source, "R_rect_00", 9, "row-major 3x3");
    const std::vector<double> P = kitti360_key(text, source, "P_rect_00", 12, "row-major 3x4");
    Kitti360Rectification out;
    out.width = side_in_pixels(S[0]);
    out.height = side_in_pixels(S[1]);
    if (out.width < 0 || out.height < 0) {
        fail_kitti360(source, "S_rect_00 = " + number_text(S[0]) + " " + number_text(S[1]) +
                                  " is not an image size; expected two whole numbers of pixels "
                                  "in [1, " +
                                  std::to_string(RgbImage::kMaxSide) + "]");
    }
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) out.R_rect(r, c) = R[3 * r + c];
    }
    const std::string problem = rotation_problem(out.R_rect);
    if (!problem.empty()) fail_kitti360(source, "R_rect_00 " + problem);
    Eigen::Matrix<double, 3, 4> Pm;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) Pm(r, c) = P[4 * r + c];
    }
    const Eigen::Matrix3d K = Pm.leftCols<3>();
    out.fx = K(0, 0);
    out.fy = K(1, 1);
    out.cx = K(0, 2);
    out.cy = K(1, 2);
    const bool pinhole =
        std::abs(K(0, 1)) <= kExactTolerance && std::abs(K(1, 0)) <= kExactTolerance &&
        std::abs(K(2, 0)) <= kExactTolerance && std::abs(K(2, 1)) <= kExactTolerance &&
        std::abs(K(2, 2) - 1.0) <= kExactTolerance;
    if (!pinhole || !(out.fx > 0.0) || !(out.fy > 0.0)) {
        fail_kitti360(source,
                      "P_rect_00's left 3x3 is not a rectified pinhole camera matrix [fx 0 cx; 0 "
                      "fy cy; 0 0 1] with fx, fy > 0 (fx = " +
                          number_text(out.fx) + ", fy = " + number_text(out.fy) +
                          "); expected KITTI-360's rectified P_rect_00, row-major 3x4");
    }
    out.t_rect = K.inverse() * Pm.col(3);
    if (!out.t_rect.allFinite()) {
        fail_kitti360(source,
                      "P_rect_00's 4th column over its focal lengths is not finite; "
                      "expected KITTI-360's rectified P_rect_00, row-major 3x4");
    }
    return out;
}

Eigen::Isometry3d parse_kitti360_cam_to_velo(std::string_view text, const fs::path& source) {
    using namespace camera_rig_internal;
    const std::string expected = "expected 12 numbers, row-major 3x4 [R|t], camera 0 -> LiDAR";
    std::vector<double> v;
    std::string bad;
    if (!parse_number_words(text, &v, &bad)) {
        fail_kitti360(source, "'" + bad + "' is not a number; " + expected);
    }
    if (v.size() != 12) {
        fail_kitti360(source, "holds " + std::to_string(v.size()) + " numbers; " + expected);
    }
    for (double x : v) {
        if (!std::isfinite(x)) fail_kitti360(source, "holds a non-finite value; " + expected);
    }
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) T.matrix()(r, c) = v[4 * r + c];
        T.matrix()(r, 3) = v[4 * r + 3];
    }
    const std::string problem = rotation_problem(T.linear());
    if (!problem.empty()) fail_kitti360(source, "the left 3x3 R " + problem + "; " + expected);
    return T;
}

RigCamera kitti360_camera(const Kitti360Rectification& rectification,
                          const Eigen::Isometry3d& T_velo_cam) {
    RigCamera camera;
    camera.name = "image_00";
    camera.width = rectification.width;
    camera.height = rectification.height;
    camera.fx = rectification.fx;
    camera.fy = rectification.fy;
    camera.cx = rectification.cx;
    camera.cy = rectification.cy;
    // Camera 0's frame -> the rectified optical frame: q = R_rect * p_cam + t'.
    Eigen::Matrix4d T_optical_cam = Eigen::Matrix4d::Identity();
    T_optical_cam.topLeftCorner<3, 3>() = rectification.R_rect;
    T_optical_cam.topRightCorner<3, 1>() = rectification.t_rect;
    // General inverses (not transposes): R_rect is orthonormal only to its file's 6 decimals.
    camera.T_lidar_camera.matrix() = T_velo_cam.matrix() * T_optical_cam.inverse();
    return camera;
}

RigCamera parse_camera_yaml(std::string_view text, const fs::path& source) {
    using namespace camera_rig_internal;
    YAML::Node root;
    try {
        root = YAML::Load(std::string(text));
    } catch (const YAML::Exception& e) {
        fail_yaml(source, std::string("is not valid YAML: ") + e.what());
    }
    if (!root.IsMap()) {
        fail_yaml(source,
                  "expected a mapping with the keys width, height, fx, fy, cx, cy, T_lidar_camera "
                  "(docs/cameras.md)");
    }
    std::string known;
    for (const char* key : kCameraYamlKeys) known += std::string(known.empty() ? "" : ", ") + key;
    std::set<std::string> seen;
    for (const auto& item : root) {
        if (!item.first.IsScalar())
            fail_yaml(source, "a key must be a single word (known: " + known + ")");
        const std::string key = item.first.Scalar();
        if (std::find(std::begin(kCameraYamlKeys), std::end(kCameraYamlKeys), key) ==
            std::end(kCameraYamlKeys)) {
            fail_yaml(source,
                      "unknown key '" + printable_excerpt(key) + "' (known: " + known + ")");
        }
        if (!seen.insert(key).second) fail_yaml(source, "key '" + key + "' appears twice");
    }
    for (const char* key : kCameraYamlKeys) {
        if (!seen.count(key)) {
            fail_yaml(source, std::string("missing key '") + key + "' (the keys are " + known +
                                  "; docs/cameras.md)");
        }
    }

    RigCamera camera;
    const std::string side_range =
        "a whole number of pixels in [1, " + std::to_string(RgbImage::kMaxSide) + "]";
    for (const char* key : {"width", "height"}) {
        const double v = yaml_number(root[key], source, key, side_range);
        const int side = side_in_pixels(v);
        if (side < 0)
            fail_yaml(source, std::string(key) + " = " + number_text(v) + " is not " + side_range);
        (std::string(key) == "width" ? camera.width : camera.height) = side;
    }
    camera.fx = yaml_number(root["fx"], source, "fx", "a focal length in pixels > 0");
    camera.fy = yaml_number(root["fy"], source, "fy", "a focal length in pixels > 0");
    for (const auto& [key, value] :
         {std::pair<const char*, double>{"fx", camera.fx}, {"fy", camera.fy}}) {
        if (!(value > 0.0)) {
            fail_yaml(source, std::string(key) + " = " + number_text(value) +
                                  " is not a focal length; expected pixels > 0");
        }
    }
    camera.cx = yaml_number(root["cx"], source, "cx", "the principal point's column in pixels");
    camera.cy = yaml_number(root["cy"], source, "cy", "the principal point's row in pixels");

    const std::string expected_T =
        "12 (3x4) or 16 (4x4, last row 0 0 0 1) numbers in one list, row-major; optical frame "
        "(x right, y down, z forward) -> LiDAR frame, metres";
    const YAML::Node T_node = root["T_lidar_camera"];
    if (!T_node.IsSequence() || (T_node.size() != 12 && T_node.size() != 16)) {
        fail_yaml(source,
                  "T_lidar_camera " +
                      (T_node.IsSequence() ? "has " + std::to_string(T_node.size()) + " numbers"
                                           : std::string("is not a list")) +
                      "; expected " + expected_T);
    }
    std::vector<double> v;
    for (std::size_t i = 0; i < T_node.size(); ++i) {
        v.push_back(yaml_number(T_node[i], source, "T_lidar_camera[" + std::to_string(i) + "]",
                                expected_T));
    }
    if (v.size() == 16) {
        const double last_row_error =
            std::max({std::abs(v[12]), std::abs(v[13]), std::abs(v[14]), std::abs(v[15] - 1.0)});
        if (last_row_error > kExactTolerance) {
            fail_yaml(source, "T_lidar_camera's last row is " + number_text(v[12]) + " " +
                                  number_text(v[13]) + " " + number_text(v[14]) + " " +
                                  number_text(v[15]) + "; expected 0 0 0 1");
        }
    }
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) camera.T_lidar_camera.matrix()(r, c) = v[4 * r + c];
    }
    const std::string problem = rotation_problem(camera.T_lidar_camera.linear());
    if (!problem.empty()) fail_yaml(source, "T_lidar_camera's left 3x3 R " + problem);
    return camera;
}

std::optional<CameraRig> find_camera_rig(const fs::path& dir) {
    using namespace camera_rig_internal;
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) return std::nullopt;
    const bool kitti360 = fs::is_directory(dir / "image_00", ec);
    const bool generic = fs::is_directory(dir / "cameras", ec);
    if (!kitti360 && !generic) return std::nullopt;
    if (kitti360 && generic) {
        throw DataError("sequence folder '" + dir.string() +
                        "' has both KITTI-360 camera images (image_00/) and a cameras/ folder; "
                        "keep one layout (docs/cameras.md)");
    }

    CameraRig rig;
    if (kitti360) {
        rig.layout = "kitti360";
        const fs::path perspective = dir / "calibration" / "perspective.txt";
        const fs::path cam_to_velo = dir / "calibration" / "calib_cam_to_velo.txt";
        for (const fs::path& file : {perspective, cam_to_velo}) {
            if (!fs::exists(file, ec)) {
                throw IoError(
                    "sequence folder '" + dir.string() +
                    "' has KITTI-360 camera images (image_00/) but no calibration file '" +
                    file.string() +
                    "': copy KITTI-360's calibration/ folder (perspective.txt, "
                    "calib_cam_to_velo.txt) into it, or remove image_00/ to map "
                    "without images");
            }
        }
        const Kitti360Rectification rectification = parse_kitti360_perspective(
            read_file_contents(perspective, "KITTI-360 calibration", "perspective.txt"),
            perspective);
        const Eigen::Isometry3d T_velo_cam = parse_kitti360_cam_to_velo(
            read_file_contents(cam_to_velo, "KITTI-360 calibration", "calib_cam_to_velo.txt"),
            cam_to_velo);
        RigCamera camera = kitti360_camera(rectification, T_velo_cam);
        camera.image_dir = dir / "image_00";
        camera.calibration_path = perspective;
        rig.cameras.push_back(std::move(camera));
        return rig;
    }

    rig.layout = "cameras";
    const fs::path cameras_dir = dir / "cameras";
    std::vector<fs::path> folders;
    for (fs::directory_iterator it(cameras_dir, ec), end; !ec && it != end; it.increment(ec)) {
        std::error_code type_ec;
        if (it->is_directory(type_ec)) folders.push_back(it->path());
    }
    if (ec) {
        throw IoError("cannot list camera folder '" + cameras_dir.string() + "': " + ec.message());
    }
    if (folders.empty()) {
        throw IoError("camera folder '" + cameras_dir.string() +
                      "' holds no camera: expected cameras/<name>/camera.yaml with that "
                      "camera's images cameras/<name>/<scan stem>.png (docs/cameras.md), or no "
                      "cameras/ folder to map without images");
    }
    std::sort(folders.begin(), folders.end());
    for (const fs::path& folder : folders) {
        const fs::path yaml = folder / "camera.yaml";
        if (!fs::exists(yaml, ec)) {
            throw IoError("camera folder '" + folder.string() + "' has no calibration '" +
                          yaml.string() +
                          "': write one with width, height, fx, fy, cx, cy and T_lidar_camera "
                          "(docs/cameras.md), or remove the folder");
        }
        RigCamera camera =
            parse_camera_yaml(read_file_contents(yaml, "camera calibration", "camera.yaml"), yaml);
        camera.name = folder.filename().string();
        camera.image_dir = folder;
        camera.calibration_path = yaml;
        rig.cameras.push_back(std::move(camera));
    }
    return rig;
}

RgbImage load_camera_image(const RigCamera& camera, const fs::path& path) {
    RgbImage image = RgbImage::read_png(path);
    if (image.width() != camera.width || image.height() != camera.height) {
        throw DataError("camera image '" + path.string() + "' is " + std::to_string(image.width()) +
                        " x " + std::to_string(image.height()) + " pixels, but camera '" +
                        camera.name + "' is calibrated for " + std::to_string(camera.width) +
                        " x " + std::to_string(camera.height) + " ('" +
                        camera.calibration_path.string() +
                        "'): use the rectified images that calibration describes");
    }
    return image;
}

}  // namespace shine
