// `shine render MAP --scans SEQ --frame N -o DIR`: images of a map from a scan's pose (range,
// surface normal and range error against that scan, in the LiDAR's own projection or a pinhole
// camera; or the map's colours through a calibrated camera of the sequence, beside the photo that
// camera took) and slices of its neural SDF, as float EXR files with PNG previews
// (docs/render.md).
//
// A frame is placed at the poses the map was made at: the map's refined poses (poses_refined.txt
// beside the mesh) when it has them, else the sequence's own; --poses overrides both.
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
#include "shine/colour/camera_view.hpp"
#include "shine/colour/exposure_record.hpp"
#include "shine/colour/photometric_score.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/io/camera_rig.hpp"
#include "shine/io/file_contents.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/model/map_file.hpp"
#include "shine/render/calibrated_camera.hpp"
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
    bool calibrated_camera = false;      ///< --calibrated-camera given
    std::string calibrated_camera_name;  ///< its value; empty: the rig's first camera
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

/// The sequence of the frame to render, at the poses to render it from, and which poses they are.
struct FrameSequence {
    ScanSequence sequence;
    std::string poses_used;  ///< for the log: which file and why
};

/// --poses when given; else the map's refined poses (poses_refined.txt beside the mesh, written
/// by `shine map` for every scan of the sequence, held-out ones included), since a map refined
/// its poses lies at them; else the sequence's own poses.
FrameSequence open_frame_sequence(const RenderOptions& opt, const fs::path& mesh_path) {
    ScanSequenceOptions seq_options;
    seq_options.poses_path = opt.poses_path;
    const fs::path refined_path = mesh_path.parent_path() / "poses_refined.txt";
    std::error_code ec;
    if (!opt.poses_path.empty() || !fs::is_regular_file(refined_path, ec)) {
        FrameSequence f{ScanSequence::open(opt.scans, seq_options), ""};
        f.poses_used = opt.poses_path.empty() ? "the sequence's own (the map has no "
                                                "poses_refined.txt)"
                                              : "--poses " + opt.poses_path;
        return f;
    }
    // The refined poses are LiDAR poses in the world frame already: no calib.txt applies.
    seq_options.poses = PoseFileUse::kIfPresent;
    const ScanSequence data = ScanSequence::open(opt.scans, seq_options);
    const std::vector<Eigen::Isometry3d> refined = read_kitti_poses(refined_path);
    if (refined.size() != data.size()) {
        throw DataError("'" + refined_path.string() + "' holds " + std::to_string(refined.size()) +
                        " poses but '" + data.directory().string() + "' has " +
                        std::to_string(data.size()) +
                        " scans: the map was made from another sequence or a selection of its "
                        "scans; give the poses to render from with --poses");
    }
    return {data.with_poses(refined), "the map's refined poses, " + refined_path.string()};
}

/// The calibrated camera --calibrated-camera names, and the photo it took with the frame's scan.
struct CalibratedView {
    CameraRig rig;
    std::size_t camera = 0;  ///< index into rig.cameras
    fs::path scan_path;      ///< the frame's scan
    fs::path photo_path;     ///< empty: the camera took no image with that scan
    std::optional<RgbImage> photo;
};

/// Finds the camera and reads the photo before the mesh, so that a folder without cameras, an
/// unknown name or a broken image is named at once.
CalibratedView find_calibrated_view(const RenderOptions& opt, const ScanSequence& sequence) {
    std::optional<CameraRig> rig =
        sequence.from_recording() ? std::nullopt : find_camera_rig(sequence.directory());
    if (!rig || rig->cameras.empty()) {
        throw IoError("'" + sequence.directory().string() +
                      "' has no cameras for --calibrated-camera: it needs KITTI-360's image_00/ "
                      "with calibration/perspective.txt and calibration/calib_cam_to_velo.txt, or "
                      "cameras/<name>/camera.yaml with that camera's images <scan stem>.png "
                      "(docs/cameras.md)");
    }
    CalibratedView view;
    view.rig = std::move(*rig);
    const std::vector<RigCamera>& cameras = view.rig.cameras;
    if (!opt.calibrated_camera_name.empty()) {
        std::string names;
        view.camera = cameras.size();
        for (std::size_t c = 0; c < cameras.size(); ++c) {
            if (cameras[c].name == opt.calibrated_camera_name) view.camera = c;
            names += (names.empty() ? "" : ", ") + cameras[c].name;
        }
        if (view.camera == cameras.size()) {
            throw ConfigError("--calibrated-camera " + opt.calibrated_camera_name + ": '" +
                              sequence.directory().string() + "' has no such camera; its " +
                              view.rig.layout + " layout has " + names);
        }
    }
    view.scan_path = sequence.scan_path(static_cast<std::size_t>(opt.frame));
    view.photo_path = view.rig.image_for_scan(view.camera, view.scan_path);
    if (!view.photo_path.empty()) {
        view.photo = load_camera_image(cameras[view.camera], view.photo_path);
    }
    return view;
}

/// Renders frame `opt.frame` of `seq` through `view`'s camera, at the exposure the run's
/// stats.json beside `mesh_path` gives that frame (none: as fitted); adds the products and prints
/// what it compared.
void render_calibrated_frame(const RenderOptions& opt, const FrameSequence& seq,
                             CalibratedView& view, const TriangleMesh& mesh,
                             const fs::path& mesh_path, const fs::path& out,
                             std::vector<Product>& products) {
    const ScanSequence& sequence = seq.sequence;
    const CameraRig& rig = view.rig;
    const RigCamera& camera = rig.cameras[view.camera];
    const std::size_t frame = static_cast<std::size_t>(opt.frame);
    const fs::path& scan_path = view.scan_path;
    const fs::path& photo_path = view.photo_path;
    std::optional<RgbImage>& photo = view.photo;
    const Eigen::Isometry3d T_map_camera =
        camera_pose_in_map(camera, sequence.pose(frame), mesh.origin_world_m);
    // The colours at this camera's exposure then: the gains the run fitted to its mapped images
    // (stats.json beside the mesh), read at this frame.
    const fs::path stats_path = mesh_path.parent_path() / "stats.json";
    double exposure_gain = 1.0;
    if (!mesh.vertex_rgb.empty() && fs::exists(stats_path)) {
        const ExposureTrack track = read_exposure_record(
            read_file_contents(stats_path, "run stats", "the stats.json beside the mesh"),
            stats_path.string());
        if (!track.empty()) {
            exposure_gain = track.gain_at(camera.name, sequence.frame_number(frame));
            std::printf("exposure: gain %.3f at frame %d, from the mapped images' (%s)\n",
                        exposure_gain, opt.frame, stats_path.c_str());
        }
    }
    CalibratedCameraRendering r =
        render_calibrated_camera(mesh, camera, T_map_camera, exposure_gain);
    std::printf("camera %s (%s layout, %d x %d, fx %.1f) of %s at frame %d's pose\n",
                camera.name.c_str(), rig.layout.c_str(), camera.width, camera.height, camera.fx,
                scan_path.filename().c_str(), opt.frame);
    std::size_t hits = 0;
    for (const std::uint8_t h : r.picture.hit) hits += h;
    const double hit_percent = 100.0 * static_cast<double>(hits) / r.picture.hit.size();
    std::printf("pixels with a map surface %.2f %%\n", hit_percent);
    switch (r.shading) {
        case CameraShading::kVertexColour:
            std::printf("colours: the mesh's vertex colours\n");
            break;
        case CameraShading::kIntensity:
            std::printf(
                "colours: none in '%s'; its LiDAR intensity shown as grey (white: %.4g, the "
                "vertices' 99th percentile)\n",
                opt.input.c_str(), r.intensity_white);
            break;
        case CameraShading::kShadedGrey:
            std::printf(
                "colours: none in '%s', nor intensity; the surface shaded grey by its angle to "
                "the camera\n",
                opt.input.c_str());
            break;
    }
    if (!photo) {
        const fs::path expected = camera.image_dir / (scan_path.stem().string() + ".png");
        std::printf("no photo %s for frame %d: rendered without a comparison\n", expected.c_str(),
                    opt.frame);
    } else if (r.shading != CameraShading::kVertexColour) {
        std::printf("no PSNR against %s: the mesh has no colours to compare\n", photo_path.c_str());
    } else {
        const PhotometricScore score = score_rendering(r.picture, *photo);
        if (score.hit_pixels == 0) {
            std::printf("no PSNR against %s: no pixel sees the map\n", photo_path.c_str());
        } else {
            std::printf("PSNR %.2f dB against %s over the %.2f %% of pixels that see the map\n",
                        score.psnr_db, photo_path.c_str(), 100.0 * score.hit_share);
        }
    }
    const std::string base = frame_name(opt.frame);
    ExrImage layers = std::move(r.layers);
    layers.attributes["shine_camera"] =
        camera.name + " (" + rig.layout + " layout, " + camera.calibration_path.string() + ")";
    layers.attributes["shine_poses"] = seq.poses_used;
    const int w = layers.width(), h = layers.height();
    const std::vector<float>& range = layers.channel("range.V");
    ColourScale range_scale;
    range_scale.max = std::ceil(finite_quantile(range, 0.99, 1.0));
    RgbImage range_preview = preview_scalar(
        range, w, h, range_scale, base + " " + camera.name + " range (black: no surface)");
    RgbImage normal_preview = preview_normals(
        layers.channel("normal.X"), layers.channel("normal.Y"), layers.channel("normal.Z"), w, h,
        base + " " + camera.name + " surface normal");
    products.push_back({out / (base + ".exr"), std::move(layers), std::nullopt});
    products.push_back({out / (base + "_camera.png"), std::nullopt, std::move(r.picture.image)});
    if (photo) products.push_back({out / (base + "_photo.png"), std::nullopt, std::move(*photo)});
    products.push_back({out / (base + "_range.png"), std::nullopt, std::move(range_preview)});
    products.push_back({out / (base + "_normal.png"), std::nullopt, std::move(normal_preview)});
}

/// Renders frame `opt.frame` of `sequence` in the LiDAR's own projection, or through the
/// pinhole `camera` when given; adds the products and prints the figures.
void render_sensor_frame(const RenderOptions& opt, const ScanSequence& sequence,
                         const TriangleMesh& mesh, std::optional<PinholeCamera> camera,
                         const std::optional<Eigen::Vector3d>& look_at_world, const fs::path& out,
                         std::vector<Product>& products) {
    const std::size_t first = products.size();
    const Scan scan = sequence.load(std::size_t(opt.frame));
    PixelRays rays;
    if (camera) {
        std::string aim = "along the LiDAR's +x, up = its +z";
        if (look_at_world) {
            // Image up is the world's up, seen from the sensor.
            const Eigen::Vector3d target_sensor = scan.T_world_sensor.inverse() * *look_at_world;
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
            model.elevations_rad.front() * 180.0 / M_PI, model.elevations_rad.back() * 180.0 / M_PI,
            model.width(), model.tilt_deg());
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
    products.push_back(
        {out / (base + "_range.png"), std::nullopt,
         preview_scalar(range, w, h, range_scale, base + " predicted range (black: no surface)")});
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
            100.0 * finite_quantile(abs_error, 0.5, 0.0), returns ? 100.0 * within / returns : 0.0);
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
    products.insert(products.begin() + static_cast<std::ptrdiff_t>(first),
                    Product{out / (base + ".exr"), image, std::nullopt});
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
    if (opt.calibrated_camera && !want_frame) {
        throw ConfigError(
            "--calibrated-camera renders frame N's view: give --scans SEQ --frame N too");
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
        const FrameSequence frame_sequence = open_frame_sequence(opt, inputs.mesh_path);
        const ScanSequence& sequence = frame_sequence.sequence;
        if (std::size_t(opt.frame) >= sequence.size()) {
            throw ConfigError("--frame " + std::to_string(opt.frame) +
                              " is outside the sequence '" + sequence.directory().string() +
                              "' of " + std::to_string(sequence.size()) +
                              " scans (frames count from 0)");
        }
        std::optional<CalibratedView> calibrated;
        if (opt.calibrated_camera) calibrated = find_calibrated_view(opt, sequence);
        const TriangleMesh mesh = read_ply_mesh(inputs.mesh_path);
        if (mesh.triangles.empty()) {
            throw IoError("'" + inputs.mesh_path.string() + "' holds no triangles to render");
        }
        std::printf("poses: %s\n", frame_sequence.poses_used.c_str());
        if (opt.calibrated_camera) {
            render_calibrated_frame(opt, frame_sequence, *calibrated, mesh, inputs.mesh_path, out,
                                    products);
        } else {
            render_sensor_frame(opt, sequence, mesh, camera, look_at_world, out, products);
        }
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
        "that scan) in the LiDAR's own projection or a pinhole camera, its colours through a "
        "calibrated camera of the sequence beside that camera's photo, and slices of its neural "
        "SDF: float EXR files with PNG previews (docs/render.md)");
    cmd->add_option("input", opt->input,
                    "`shine map` or `shine tsdf` output directory, a PLY mesh, or a map.vdb "
                    "(slices only)")
        ->required();
    cmd->add_option("--scans,scans", opt->scans,
                    "sequence whose scan gives the pose and rays (--scans SEQ, or SEQ after the "
                    "map)");
    cmd->add_option("--frame", opt->frame, "index of that scan in the sequence (from 0)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--poses", opt->poses_path,
                    "pose file (default: the map's poses_refined.txt when it has one, else the "
                    "sequence's)");
    cmd->add_option("-o,--output", opt->out, "output directory")->required();
    auto* camera =
        cmd->add_option("--camera", opt->camera,
                        "pinhole camera fx,fy,cx,cy,w,h (pixels) at the sensor, looking along the "
                        "LiDAR's forward axis (+x) with its +z up; default: the LiDAR's own "
                        "projection");
    auto* look_at = cmd->add_option(
        "--camera-look-at", opt->camera_look_at,
        "aim the --camera at this world point x,y,z (m, the poses' frame), image up = world +z");
    auto* rotation =
        cmd->add_option("--camera-rotation", opt->camera_rotation,
                        "aim the --camera by a row-major 3x3 rotation from its optical frame (x "
                        "right, y down, z forward) to the LiDAR's; forward is 0,0,1,-1,0,0,0,-1,0")
            ->excludes(look_at);
    auto* calibrated =
        cmd->add_option("--calibrated-camera", opt->calibrated_camera_name,
                        "render the map's colours through this camera of the sequence's rig "
                        "(docs/cameras.md; default: its first) at the frame's pose, beside the "
                        "photo it took, with the PSNR between them; give a NAME as "
                        "--calibrated-camera=NAME")
            ->expected(0, 1)
            ->excludes(camera)
            ->excludes(look_at)
            ->excludes(rotation);
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
    cmd->callback([opt, calibrated, &action] {
        opt->calibrated_camera = calibrated->count() > 0;
        action = [opt] { return run_render(*opt); };
    });
});

}  // namespace
}  // namespace shine::cli
