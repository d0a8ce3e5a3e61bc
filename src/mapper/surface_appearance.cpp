#include "shine/mapper/surface_appearance.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <chrono>
#include <cmath>
#include <cstdlib>

#include "shine/bake/level_set_file.hpp"
#include "shine/bake/surface_attribute_grids.hpp"
#include "shine/colour/camera_view.hpp"
#include "shine/colour/mesh_raster.hpp"
#include "shine/colour/reflectance_voxels.hpp"
#include "shine/colour/vertex_colour_fit.hpp"
#include "shine/core/stopwatch.hpp"
#include "shine/io/ply.hpp"
#include "shine/mapper/sequence_deskew.hpp"

namespace shine {
namespace fs = std::filesystem;

std::vector<Eigen::Vector3d> vertex_normals(const TriangleMesh& mesh) {
    std::vector<Eigen::Vector3d> normals(mesh.vertices.size(), Eigen::Vector3d::Zero());
    for (const Eigen::Vector3i& t : mesh.triangles) {
        const Eigen::Vector3d a = mesh.vertices[t[0]].cast<double>();
        const Eigen::Vector3d n =
            (mesh.vertices[t[1]].cast<double>() - a).cross(mesh.vertices[t[2]].cast<double>() - a);
        for (int k = 0; k < 3; ++k) normals[t[k]] += n;  // |n| = twice the area
    }
    for (Eigen::Vector3d& n : normals) {
        const double length = n.norm();
        n = length > 0.0 ? Eigen::Vector3d(n / length) : Eigen::Vector3d::Zero();
    }
    return normals;
}

std::size_t fill_unseen_colours(const TriangleMesh& mesh,
                                std::vector<std::array<std::uint8_t, 3>>& rgb,
                                std::vector<std::uint8_t>& known, int rings) {
    std::size_t filled = 0;
    for (int ring = 0; ring < rings; ++ring) {
        std::vector<Eigen::Vector3d> sum(rgb.size(), Eigen::Vector3d::Zero());
        std::vector<std::uint32_t> count(rgb.size(), 0);
        for (const Eigen::Vector3i& t : mesh.triangles) {
            for (int k = 0; k < 3; ++k) {
                const int to = t[k];
                if (known[to]) continue;
                for (int j = 1; j <= 2; ++j) {
                    const int from = t[(k + j) % 3];
                    if (!known[from]) continue;
                    sum[to] += Eigen::Vector3d(rgb[from][0], rgb[from][1], rgb[from][2]);
                    ++count[to];
                }
            }
        }
        std::size_t added = 0;
        for (std::size_t i = 0; i < rgb.size(); ++i) {
            if (count[i] == 0) continue;
            const Eigen::Vector3d mean = sum[i] / count[i];
            for (int c = 0; c < 3; ++c) rgb[i][c] = static_cast<std::uint8_t>(std::lround(mean[c]));
            known[i] = 1;
            ++added;
        }
        filled += added;
        if (added == 0) break;
    }
    return filled;
}

void fill_with_mean_colour(std::vector<std::array<std::uint8_t, 3>>& rgb,
                           const std::vector<std::uint8_t>& known) {
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    double count = 0.0;
    for (std::size_t i = 0; i < rgb.size(); ++i) {
        if (!known[i]) continue;
        sum += Eigen::Vector3d(rgb[i][0], rgb[i][1], rgb[i][2]);
        count += 1.0;
    }
    if (count == 0.0) return;
    std::array<std::uint8_t, 3> mean;
    for (int c = 0; c < 3; ++c) mean[c] = static_cast<std::uint8_t>(std::lround(sum[c] / count));
    for (std::size_t i = 0; i < rgb.size(); ++i) {
        if (!known[i]) rgb[i] = mean;
    }
}

void add_scan_reflectance(ReflectanceVoxels& voxels, const Scan& scan,
                          const Eigen::Vector3d& origin_world_m,
                          const PreprocessConfig& preprocess) {
    if (scan.intensity.empty()) return;
    std::vector<Eigen::Vector3d> points;
    std::vector<float> intensity;
    points.reserve(scan.points_sensor.size());
    intensity.reserve(scan.points_sensor.size());
    for (std::size_t k = 0; k < scan.points_sensor.size(); ++k) {
        const Eigen::Vector3d p = scan.points_sensor[k].cast<double>();
        const double range_m = p.norm();
        if (!std::isfinite(range_m) || range_m < preprocess.min_range_m ||
            range_m > preprocess.max_range_m) {
            continue;
        }
        Eigen::Vector3d p_map = scan.T_world_sensor * p;
        p_map -= origin_world_m;
        points.push_back(p_map);
        intensity.push_back(scan.intensity[k]);
    }
    voxels.add(points, intensity);
}

namespace surface_appearance_internal {
namespace {

/// The map-frame points of every mapped scan with their intensities, accumulated in voxels.
ReflectanceVoxels accumulate_reflectance(const ScanSequence& mapped, const MapperConfig& config,
                                         const Eigen::Vector3d& origin_world_m, double voxel_m) {
    ReflectanceVoxels voxels(voxel_m);
    const bool deskew =
        deskew_active(config.deskew, config.odometry.estimate_poses, mapped.has_sweep_times());
    DeskewStats ignored;
    for (std::size_t i = 0; i < mapped.size(); ++i) {
        Scan scan = mapped.load(i);
        if (scan.intensity.empty()) continue;
        if (deskew) deskew_with_sequence_poses(scan, mapped, i, config.deskew, ignored);
        add_scan_reflectance(voxels, scan, origin_world_m, config.preprocess);
    }
    return voxels;
}

}  // namespace
}  // namespace surface_appearance_internal

SurfaceAppearanceStats add_surface_appearance(const fs::path& out_dir, const ScanSequence& mapped,
                                              const MapperConfig& config,
                                              const std::optional<CameraRig>& rig,
                                              const SurfaceAppearanceConfig& appearance,
                                              const ReflectanceVoxels* reflectance_map,
                                              WrittenSurface* written) {
    using namespace surface_appearance_internal;
    const auto start = std::chrono::steady_clock::now();
    SurfaceAppearanceStats stats;
    if (mapped.size() == 0) return stats;
    // Is there anything to fuse? Images of mapped scans, or intensity in the first scan.
    bool any_image = false;
    for (std::size_t i = 0; i < mapped.size() && rig && !any_image; ++i) {
        for (std::size_t c = 0; c < rig->cameras.size(); ++c) {
            any_image = any_image || !rig->image_for_scan(c, mapped.scan_path(i)).empty();
        }
    }
    const bool any_intensity = !mapped.load(0).intensity.empty();
    if (!any_image && !any_intensity) return stats;

    const fs::path mesh_path = out_dir / "mesh.ply";
    const fs::path surface_path = out_dir / "surface.vdb";
    // The mesh and the level set: taken over, or read side by side.
    TriangleMesh mesh;
    openvdb::FloatGrid::Ptr level_set;
    // A mesh taken over goes back when this returns, as mesh.ply then holds it.
    struct GiveBack {
        TriangleMesh& mesh;
        WrittenSurface* to = nullptr;
        ~GiveBack() {
            if (to) to->mesh = std::move(mesh);
        }
    } give_back{mesh};
    if (written && written->level_set) {
        mesh = std::move(written->mesh);
        level_set = std::move(written->level_set);
        give_back.to = written;
    } else {
        tbb::parallel_invoke([&] { mesh = read_ply_mesh(mesh_path); },
                             [&] { level_set = read_level_set(surface_path); });
    }
    const double voxel_m = level_set->transform().voxelSize()[0];
    stats.vertices = mesh.vertices.size();
    openvdb::GridPtrVec extra;

    if (any_image) {
        // One image at a time: loaded, placed, the mesh rasterised into it, its pixels added to
        // the fit, and dropped.
        VertexColourFit fit(mesh, appearance.fit);
        std::vector<ExposureGain> exposure;
        for (std::size_t i = 0; i < mapped.size(); ++i) {
            for (const CameraView& view : load_camera_views(
                     *rig, {mapped.scan_path(i)}, {mapped.pose(i)}, mesh.origin_world_m, {i})) {
                fit.add_view(
                    view, rasterize_mesh(mesh, view.camera, view.T_map_camera, appearance.near_m));
                exposure.push_back({view.camera.name, mapped.frame_number(i), 1.0});
                ++stats.views;
            }
        }
        VertexColours fused = fit.solve();
        for (std::size_t k = 0; k < exposure.size(); ++k) exposure[k].gain = fused.view_gains[k];
        stats.exposure = ExposureTrack(std::move(exposure));
        stats.coloured_vertices = fused.coloured;
        std::vector<std::uint8_t> known(fused.support.size());
        for (std::size_t i = 0; i < known.size(); ++i) known[i] = fused.support[i] > 0.0f;
        stats.filled_vertices = fill_unseen_colours(mesh, fused.rgb, known, appearance.fill_rings);
        extra.push_back(color_grid_from_vertices(*level_set, mesh.vertices, fused.rgb, known));
        fill_with_mean_colour(fused.rgb, known);
        mesh.vertex_rgb = std::move(fused.rgb);
        stats.colour = true;
    }
    if (any_intensity) {
        std::optional<ReflectanceVoxels> reloaded;
        if (!reflectance_map) {
            reloaded = accumulate_reflectance(mapped, config, mesh.origin_world_m, voxel_m);
        }
        const ReflectanceVoxels& reflectance = reflectance_map ? *reflectance_map : *reloaded;
        stats.intensity_points = reflectance.num_points();
        if (!reflectance.empty()) {
            mesh.vertex_intensity.resize(mesh.vertices.size());
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, mesh.vertices.size(), 4096),
                              [&](const tbb::blocked_range<std::size_t>& r) {
                                  for (std::size_t i = r.begin(); i != r.end(); ++i) {
                                      mesh.vertex_intensity[i] =
                                          reflectance.at(mesh.vertices[i].cast<double>());
                                  }
                              });
            for (const float v : mesh.vertex_intensity)
                stats.intensity_vertices += std::isfinite(v);
            extra.push_back(
                intensity_grid_from_vertices(*level_set, mesh.vertices, mesh.vertex_intensity));
            stats.intensity = true;
        }
    }
    if (!stats.colour && !stats.intensity) return stats;
    for (const auto& grid : extra) {
        const std::size_t active = grid->activeVoxelCount();
        (grid->getName() == kColorGridName ? stats.coloured_voxels : stats.intensity_voxels) =
            active;
    }
    // Each file is written atomically on its own core.
    tbb::parallel_invoke([&] { write_surface_grids(surface_path, level_set, extra); },
                         [&] { write_ply_mesh(mesh_path, mesh); });
    stats.seconds = seconds_since(start);
    return stats;
}

}  // namespace shine
