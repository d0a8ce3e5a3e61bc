#include "map_appearance.hpp"

#include <algorithm>
#include <cstdio>

#include "shine/colour/camera_view.hpp"
#include "shine/colour/exposure_record.hpp"
#include "shine/colour/photometric_score.hpp"
#include "shine/io/ply.hpp"
#include "shine/mapper/surface_appearance.hpp"

namespace shine::cli {
namespace fs = std::filesystem;

std::optional<CameraRig> find_sequence_cameras(const ScanSequence& selected, bool quiet) {
    if (selected.from_recording()) return std::nullopt;
    std::optional<CameraRig> rig = find_camera_rig(selected.directory());
    if (rig && !quiet) {
        std::string names;
        for (const RigCamera& c : rig->cameras) names += (names.empty() ? "" : ", ") + c.name;
        std::printf("cameras (%s layout): %s; their images colour the surface (docs/colour.md)\n",
                    rig->layout.c_str(), names.c_str());
    }
    return rig;
}

ExposureTrack add_map_appearance(const fs::path& out, const ScanSequence& mapped,
                                 const MapperConfig& config, const std::optional<CameraRig>& rig,
                                 const ReflectanceVoxels* reflectance, WrittenSurface* written,
                                 nlohmann::json& json) {
    const SurfaceAppearanceStats s =
        add_surface_appearance(out, mapped, config, rig, {}, reflectance, written);
    if (!s.colour && !s.intensity) return s.exposure;
    const auto share = [](std::size_t part, std::size_t whole) {
        return whole ? 100.0 * static_cast<double>(part) / static_cast<double>(whole) : 0.0;
    };
    json["appearance"] = {{"colour", s.colour},
                          {"intensity", s.intensity},
                          {"images", s.views},
                          {"vertices", s.vertices},
                          {"coloured_vertices", s.coloured_vertices},
                          {"filled_vertices", s.filled_vertices},
                          {"coloured_voxels", s.coloured_voxels},
                          {"intensity_points", s.intensity_points},
                          {"intensity_vertices", s.intensity_vertices},
                          {"intensity_voxels", s.intensity_voxels},
                          {"seconds", s.seconds}};
    if (!s.exposure.empty()) {
        json["appearance"]["exposure"] = nlohmann::json::parse(exposure_record_json(s.exposure));
    }
    std::string what;
    if (s.colour) {
        char text[160];
        std::snprintf(text, sizeof(text),
                      "colour from %zu images on %.1f %% of the mesh's vertices (%.1f %% more "
                      "from their neighbours)",
                      s.views, share(s.coloured_vertices, s.vertices),
                      share(s.filled_vertices, s.vertices));
        what += text;
        if (!s.exposure.empty()) {
            const auto [low, high] = std::minmax_element(
                s.exposure.gains().begin(), s.exposure.gains().end(),
                [](const ExposureGain& a, const ExposureGain& b) { return a.gain < b.gain; });
            std::snprintf(text, sizeof(text), ", each image's exposure fitted (gains %.3f-%.3f)",
                          low->gain, high->gain);
            what += text;
        }
    }
    if (s.intensity) {
        char text[128];
        std::snprintf(text, sizeof(text), "%sreflectance from %.2f M points on %.1f %% of them",
                      what.empty() ? "" : "; ", s.intensity_points / 1e6,
                      share(s.intensity_vertices, s.vertices));
        what += text;
    }
    std::printf("%s, in %.1f s (mesh.ply and surface.vdb)\n", what.c_str(), s.seconds);
    return s.exposure;
}

void score_heldout_colours(const fs::path& out, const ScanSequence& scored,
                           const HoldoutSplit& split, const std::optional<CameraRig>& rig,
                           const ExposureTrack& exposure, nlohmann::json& json) {
    if (!rig || split.heldout.empty()) return;
    const TriangleMesh mesh = read_ply_mesh(out / "mesh.ply");
    if (mesh.vertex_rgb.empty()) return;
    const auto views_of = [&](const std::vector<std::size_t>& indices) {
        std::vector<fs::path> paths;
        std::vector<Eigen::Isometry3d> poses;
        for (const std::size_t i : indices) {
            paths.push_back(scored.scan_path(i));
            poses.push_back(scored.pose(i));
        }
        return load_camera_views(*rig, paths, poses, mesh.origin_world_m, indices);
    };
    const std::vector<CameraView> heldout = views_of(split.heldout);
    if (heldout.empty()) return;
    // Each held-out camera at the exposure of the mapped images around it.
    std::vector<double> gains;
    for (const CameraView& view : heldout) {
        gains.push_back(exposure.gain_at(view.camera.name, scored.frame_number(view.scan_index)));
    }
    const HeldoutColourScores scores =
        score_heldout_images(mesh, views_of(split.mapped), heldout, gains);
    nlohmann::json frames = nlohmann::json::array();
    for (std::size_t k = 0; k < scores.frames.size(); ++k) {
        const HeldoutImageScore& f = scores.frames[k];
        frames.push_back({{"scan", f.scan_index},
                          {"image", f.image_path.string()},
                          {"psnr_db", f.map.psnr_db},
                          {"baseline_psnr_db", f.baseline.psnr_db},
                          {"hit_share", f.map.hit_share},
                          {"exposure_gain", gains[k]}});
    }
    json["heldout_colour"] = {{"images", scores.frames.size()},
                              {"psnr_db", scores.map_psnr_db},
                              {"baseline_psnr_db", scores.baseline_psnr_db},
                              {"hit_share", scores.hit_share},
                              {"frames", frames}};
    std::printf(
        "held-out images (%zu): the coloured map scores PSNR %.2f dB over the %.1f %% of pixels "
        "that see it; the nearest-camera baseline on the same mesh %.2f dB\n",
        scores.frames.size(), scores.map_psnr_db, 100.0 * scores.hit_share,
        scores.baseline_psnr_db);
}

}  // namespace shine::cli
