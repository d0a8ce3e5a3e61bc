// `shine render MAP --scans SEQ --frame N -o DIR`: images of a map from a scan's pose (range,
// surface normal and range error against that scan, in the LiDAR's own projection or a pinhole
// camera) and slices of its neural SDF, as float EXR files with PNG previews (docs/render.md).
//
// Everything is read, checked and rendered in memory before the first file is written, so bad
// input (a frame out of range, a short pose file, a file that is not a mesh or a map) leaves no
// output; each file is written under a temporary name and renamed.
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "command_registry.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/model/map_file.hpp"
#include "shine/render/exr_image.hpp"
#include "shine/render/lidar_model.hpp"
#include "shine/render/map_render.hpp"
#include "shine/render/pinhole_camera.hpp"
#include "shine/render/preview.hpp"
#include "shine/render/sdf_slice.hpp"

namespace shine::cli {
namespace {
namespace fs = std::filesystem;

/// Error previews use one fixed scale, so images of different maps compare at a glance.
constexpr double kErrorScaleM = 0.2;

struct RenderOptions {
    std::string input;
    std::string scans;
    std::string poses_path;
    int frame = -1;
    std::string out;
    std::string camera;
    std::string camera_look_at;
    std::string camera_rotation;
    std::vector<std::string> slices;
    double pixel_m = 0.0;
    double min_range_m = 1.5;
    double max_range_m = 60.0;
    int threads = 0;
};

/// A file to write once everything is ready.
struct Product {
    fs::path path;
    std::optional<ExrImage> exr;
    std::optional<RgbImage> png;
};

struct Inputs {
    fs::path mesh_path;  ///< empty: none
    fs::path map_path;   ///< empty: none
};

Inputs resolve_inputs(const fs::path& input) {
    Inputs in;
    if (fs::is_directory(input)) {
        if (fs::exists(input / "mesh.ply")) in.mesh_path = input / "mesh.ply";
        if (fs::exists(input / "map.vdb")) in.map_path = input / "map.vdb";
        if (in.mesh_path.empty() && in.map_path.empty()) {
            throw IoError(
                "'" + input.string() +
                "' holds neither mesh.ply nor map.vdb: give a `shine map` or `shine tsdf` "
                "output directory, a PLY mesh or a map.vdb");
        }
    } else if (!fs::exists(input)) {
        throw IoError("'" + input.string() + "' does not exist");
    } else if (input.extension() == ".ply") {
        in.mesh_path = input;
    } else if (input.extension() == ".vdb") {
        in.map_path = input;
    } else {
        throw IoError("'" + input.string() +
                      "' is neither a directory, a .ply mesh nor a .vdb map");
    }
    return in;
}

std::string frame_name(int frame) {
    char name[32];
    std::snprintf(name, sizeof(name), "frame_%06d", frame);
    return name;
}

int run_render(const RenderOptions& opt) {
    auto thread_limit = limit_threads(opt.threads);
    const bool want_frame = !opt.scans.empty() || opt.frame >= 0;
    if (!want_frame && opt.slices.empty()) {
        throw ConfigError(
            "nothing to render: give --scans SEQ --frame N (images from that scan's "
            "pose) and/or --slice z=VALUE (an SDF slice)");
    }
    if (want_frame && (opt.scans.empty() || opt.frame < 0)) {
        throw ConfigError(
            "--scans and --frame go together: the sequence and the scan whose pose "
            "and rays to render");
    }
    // Parse everything first.
    std::optional<PinholeCamera> camera;
    if (!opt.camera.empty()) camera = parse_pinhole_camera(opt.camera);
    if (!camera && (!opt.camera_look_at.empty() || !opt.camera_rotation.empty())) {
        throw ConfigError(
            "--camera-look-at and --camera-rotation aim a pinhole camera: give --camera "
            "fx,fy,cx,cy,w,h too");
    }
    std::optional<Eigen::Vector3d> look_at_world;
    if (!opt.camera_look_at.empty()) {
        look_at_world = parse_point3(opt.camera_look_at, "--camera-look-at");
    }
    if (!opt.camera_rotation.empty()) {
        camera->R_sensor_camera = parse_camera_rotation(opt.camera_rotation);
    }
    std::vector<SlicePlane> planes;
    for (const std::string& s : opt.slices) planes.push_back(parse_slice_plane(s));
    const Inputs inputs = resolve_inputs(opt.input);

    std::vector<Product> products;
    const fs::path out(opt.out);
    if (want_frame) {
        if (inputs.mesh_path.empty()) {
            throw IoError("'" + opt.input +
                          "' has no mesh (mesh.ply) to render images of; a map.vdb alone gives "
                          "only --slice images");
        }
        ScanSequenceOptions seq_options;
        seq_options.poses_path = opt.poses_path;
        const ScanSequence sequence = ScanSequence::open(opt.scans, seq_options);
        if (std::size_t(opt.frame) >= sequence.size()) {
            throw ConfigError("--frame " + std::to_string(opt.frame) +
                              " is outside the sequence '" + sequence.directory().string() +
                              "' of " + std::to_string(sequence.size()) +
                              " scans (frames count from 0)");
        }
        const TriangleMesh mesh = read_ply_mesh(inputs.mesh_path);
        if (mesh.triangles.empty()) {
            throw IoError("'" + inputs.mesh_path.string() + "' holds no triangles to render");
        }
        const Scan scan = sequence.load(std::size_t(opt.frame));
        PixelRays rays;
        if (camera) {
            std::string aim = "along the LiDAR's +x, up = its +z";
            if (look_at_world) {
                // Image up is the world's up, seen from the sensor.
                const Eigen::Vector3d target_sensor =
                    scan.T_world_sensor.inverse() * *look_at_world;
                const Eigen::Vector3d up_sensor =
                    scan.T_world_sensor.linear().transpose() * Eigen::Vector3d::UnitZ();
                camera->R_sensor_camera = camera_looking_at(target_sensor, up_sensor);
                aim = "at " + opt.camera_look_at + " (world), up = world +z";
            } else if (!opt.camera_rotation.empty()) {
                aim = "as --camera-rotation gives";
            }
            rays = camera_pixel_rays(*camera);
            std::printf("pinhole camera %d x %d looking %s\n", camera->width, camera->height,
                        aim.c_str());
        } else {
            const SphericalLidarModel model = infer_spherical_lidar(scan.points_sensor);
            rays = scan_pixel_rays(model, scan.points_sensor, opt.min_range_m, opt.max_range_m);
            std::printf(
                "LiDAR model of %s: %d rings (%.2f to %.2f deg) x %d columns, spin axis "
                "tilted %.2f deg from sensor z\n",
                scan.source.filename().c_str(), model.height(),
                model.elevations_rad.front() * 180.0 / M_PI,
                model.elevations_rad.back() * 180.0 / M_PI, model.width(), model.tilt_deg());
        }
        const MeshRenderer renderer(mesh);
        const ExrImage image = renderer.render(rays, scan.T_world_sensor);
        const std::string base = frame_name(opt.frame);
        const int w = image.width(), h = image.height();
        const std::vector<float>& range = image.channel("range.V");
        if (camera) {
            const auto surface =
                std::count_if(range.begin(), range.end(), [](float r) { return !std::isnan(r); });
            std::printf("pixels with a map surface %.2f %%\n",
                        100.0 * static_cast<double>(surface) / static_cast<double>(range.size()));
        }
        ColourScale range_scale;
        range_scale.max = std::ceil(finite_quantile(range, 0.99, 1.0));
        products.push_back({out / (base + "_range.png"), std::nullopt,
                            preview_scalar(range, w, h, range_scale,
                                           base + " predicted range (black: no surface)")});
        products.push_back(
            {out / (base + "_normal.png"), std::nullopt,
             preview_normals(image.channel("normal.X"), image.channel("normal.Y"),
                             image.channel("normal.Z"), w, h, base + " surface normal")});
        if (image.has_channel("error.V")) {
            const std::vector<float>& error = image.channel("error.V");
            const std::vector<float>& measured = image.channel("measured.V");
            std::size_t returns = 0, hits = 0, within = 0;
            std::vector<float> abs_error;
            for (std::size_t i = 0; i < error.size(); ++i) {
                if (std::isnan(measured[i])) continue;
                ++returns;
                if (std::isnan(error[i])) continue;
                ++hits;
                abs_error.push_back(std::abs(error[i]));
                within += std::abs(error[i]) <= 0.10;
            }
            std::printf(
                "pixels with a return %zu, with a map surface %.2f %%, median |error| "
                "%.2f cm, within 10 cm %.2f %%\n",
                returns, returns ? 100.0 * hits / returns : 0.0,
                100.0 * finite_quantile(abs_error, 0.5, 0.0),
                returns ? 100.0 * within / returns : 0.0);
            ColourScale error_scale;
            error_scale.min = -kErrorScaleM;
            error_scale.max = kErrorScaleM;
            error_scale.diverging = true;
            PreviewLayout layout;
            layout.missing_colour = {255, 0, 255};
            products.push_back(
                {out / (base + "_error.png"), std::nullopt,
                 preview_scalar(error, w, h, error_scale,
                                base + " measured - predicted range (magenta: return, no surface)",
                                layout, measured)});
        }
        products.insert(products.begin(), Product{out / (base + ".exr"), image, std::nullopt});
    }
    if (!planes.empty()) {
        if (inputs.map_path.empty()) {
            throw IoError("'" + opt.input +
                          "' has no neural map (map.vdb) to slice: --slice needs a `shine map` "
                          "output directory or its map.vdb");
        }
        const LoadedMap map = load_neural_map(inputs.map_path);
        SdfSliceConfig config;
        config.pixel_m = opt.pixel_m;
        for (const SlicePlane& plane : planes) {
            const ExrImage slice = slice_neural_sdf(map.sdf, plane, config);
            const double scale_m = 0.5;
            ColourScale scale;
            scale.min = -scale_m;
            scale.max = scale_m;
            scale.diverging = true;
            PreviewLayout layout;
            layout.min_height_px = 1;
            layout.zero_level = true;
            layout.nan_colour = {128, 128, 128};
            const std::string base = "slice_" + plane.label();
            products.push_back({out / (base + ".exr"), slice, std::nullopt});
            products.push_back(
                {out / (base + ".png"), std::nullopt,
                 preview_scalar(slice.channel("sdf.V"), slice.width(), slice.height(), scale,
                                base + " SDF (black: zero level; grey: unobserved)", layout)});
        }
    }
    ensure_directory(out);
    for (const Product& p : products) {
        if (p.exr) write_exr(p.path, *p.exr);
        if (p.png) p.png->write_png(p.path);
        std::printf("wrote %s\n", p.path.c_str());
    }
    return 0;
}

const RegisterCommand kRegisterRender(55, [](CLI::App& app, Action& action) {
    auto opt = std::make_shared<RenderOptions>();
    CLI::App* cmd = app.add_subcommand(
        "render",
        "Render a map from a scan's pose (predicted range, surface normal, range error against "
        "that scan) in the LiDAR's own projection or a pinhole camera, and slices of its neural "
        "SDF: float EXR files with PNG previews (docs/render.md)");
    cmd->add_option("input", opt->input,
                    "`shine map` or `shine tsdf` output directory, a PLY mesh, or a map.vdb "
                    "(slices only)")
        ->required();
    cmd->add_option("--scans", opt->scans, "sequence whose scan gives the pose and rays");
    cmd->add_option("--frame", opt->frame, "index of that scan in the sequence (from 0)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--poses", opt->poses_path, "pose file (default: found in the sequence)");
    cmd->add_option("-o,--output", opt->out, "output directory")->required();
    cmd->add_option("--camera", opt->camera,
                    "pinhole camera fx,fy,cx,cy,w,h (pixels) at the sensor, looking along the "
                    "LiDAR's forward axis (+x) with its +z up; default: the LiDAR's own "
                    "projection");
    auto* look_at = cmd->add_option(
        "--camera-look-at", opt->camera_look_at,
        "aim the --camera at this world point x,y,z (m, the poses' frame), image up = world +z");
    cmd->add_option("--camera-rotation", opt->camera_rotation,
                    "aim the --camera by a row-major 3x3 rotation from its optical frame (x "
                    "right, y down, z forward) to the LiDAR's; forward is 0,0,1,-1,0,0,0,-1,0")
        ->excludes(look_at);
    cmd->add_option("--slice", opt->slices,
                    "SDF slice on an axis-aligned world plane, e.g. z=1.5 (repeatable)");
    cmd->add_option("--pixel-m", opt->pixel_m, "slice pixel size (default: the map's leaf size)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--min-range-m", opt->min_range_m, "returns measured closer are not used")
        ->capture_default_str();
    cmd->add_option("--max-range-m", opt->max_range_m, "returns measured farther are not used")
        ->capture_default_str();
    cmd->add_option("--threads", opt->threads, "worker threads (0 = all cores)")
        ->capture_default_str();
    cmd->callback([opt, &action] { action = [opt] { return run_render(*opt); }; });
});

}  // namespace
}  // namespace shine::cli
