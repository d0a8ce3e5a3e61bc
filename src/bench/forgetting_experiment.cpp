#include "shine/bench/forgetting_experiment.hpp"

#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "shine/bench/mesh_render.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/raster.hpp"
#include "shine/core/stopwatch.hpp"
#include "shine/eval/mesh_sampling.hpp"
#include "shine/eval/metrics_report.hpp"
#include "shine/eval/nearest_distance.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/preprocess.hpp"
#include "shine/mapper/incremental_sequence.hpp"
#include "shine/mapper/map_sequence.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace forgetting_internal {
namespace {

/// Colour scale of the figure: distance to the observed reference, 0 .. kErrorScaleM.
constexpr double kErrorScaleM = 0.10;
/// Density of the reference samples the figure's distances are measured to (one per ~2.2 cm,
/// so the colours' floor is about 1 cm).
constexpr double kColourSampleDensityPerM2 = 2000.0;
/// The early-region close-up frames the first quarter's sensor positions plus this margin.
constexpr float kCloseUpMarginM = 20.0f;

/// The early region: voxels holding a preprocessed point of the first `frames` scans.
VoxelRegion early_region(const ScanSequence& sequence, std::size_t frames,
                         const PreprocessConfig& preprocess, double voxel_m,
                         Eigen::AlignedBox3f& sensor_box) {
    VoxelRegion region(voxel_m);
    for (std::size_t i = 0; i < frames; ++i) {
        const Scan scan = sequence.load(i);
        const std::vector<Eigen::Vector3f> points_sensor =
            preprocess_scan(scan.points_sensor, preprocess, scan.source);
        std::vector<Eigen::Vector3f> points_world;
        points_world.reserve(points_sensor.size());
        for (const auto& p : points_sensor) {
            points_world.push_back((scan.T_world_sensor * p.cast<double>()).cast<float>());
        }
        region.add_points(points_world);
        sensor_box.extend(scan.T_world_sensor.translation().cast<float>());
    }
    return region;
}

/// The triangles whose centroid lies in `box`.
TriangleMesh crop_to_box(const TriangleMesh& mesh, const Eigen::AlignedBox3f& box) {
    TriangleMesh out;
    std::vector<int> index(mesh.vertices.size(), -1);
    for (const auto& t : mesh.triangles) {
        const Eigen::Vector3f c =
            (mesh.vertices[t[0]] + mesh.vertices[t[1]] + mesh.vertices[t[2]]) / 3.0f;
        if (!box.contains(c)) continue;
        Eigen::Vector3i r;
        for (int k = 0; k < 3; ++k) {
            if (index[t[k]] < 0) {
                index[t[k]] = static_cast<int>(out.vertices.size());
                out.vertices.push_back(mesh.vertices[t[k]]);
            }
            r[k] = index[t[k]];
        }
        out.triangles.push_back(r);
    }
    return out;
}

std::vector<Rgb> error_colours(const TriangleMesh& mesh,
                               const std::vector<Eigen::Vector3f>& reference_points) {
    const std::vector<float> d = nearest_distances_m(reference_points, mesh.vertices, kErrorScaleM);
    std::vector<Rgb> colours(d.size());
    for (std::size_t i = 0; i < d.size(); ++i) colours[i] = error_colour(d[i], kErrorScaleM);
    return colours;
}

std::string percent(double ratio) {
    char b[32];
    std::snprintf(b, sizeof(b), "%.1f%%", 100.0 * ratio);
    return b;
}
std::string centimetres(double m) {
    char b[32];
    std::snprintf(b, sizeof(b), "%.2f cm", 100.0 * m);
    return b;
}

std::string run_title(const ForgettingRun& run) {
    if (run.name == "batch") return "batch mode";
    if (run.regularization_weight == 0.0f) return "incremental, no regularisation";
    char b[64];
    std::snprintf(b, sizeof(b), "incremental, lambda_r = %g", run.regularization_weight);
    return b;
}

void write_figure(const ForgettingReport& report, const TriangleMesh& reference,
                  const Eigen::AlignedBox3f& close_up, int panel_width, const fs::path& path) {
    const TriangleMesh observed_reference = [&] {
        TriangleMesh r = reference;
        TriangleMesh out;
        out.vertices = r.vertices;
        for (std::size_t i = 0; i < r.triangles.size(); ++i) {
            if (r.face_observed.empty() || r.face_observed[i])
                out.triangles.push_back(r.triangles[i]);
        }
        return out;
    }();
    const std::vector<Eigen::Vector3f> reference_points =
        sample_mesh_surface(observed_reference, kColourSampleDensityPerM2, 1);

    MeshRenderView whole_view;
    whole_view.azimuth_deg = -90.0;  // from the -y side, the street running left to right
    whole_view.elevation_deg = 55.0;
    for (const auto& run : report.runs) {
        for (const auto& v : run.mesh.vertices) whole_view.bounds.extend(v);
    }
    MeshRenderView close_view = whole_view;
    close_view.azimuth_deg = -115.0;
    close_view.elevation_deg = 40.0;
    close_view.bounds = close_up;

    const int cols = static_cast<int>(report.runs.size());
    const int panel_w = panel_width;
    const int panel_h = panel_width * 9 / 16;
    const int title_h = 44, legend_h = 40, gap = 8;
    RgbImage image(cols * panel_w + (cols + 1) * gap, 2 * (panel_h + title_h) + legend_h + 2 * gap,
                   Rgb{255, 255, 255});
    for (int c = 0; c < cols; ++c) {
        const ForgettingRun& run = report.runs[c];
        const int x0 = gap + c * (panel_w + gap);
        // Row 1: the whole map.
        draw_text(image, x0 + 4, 4, run_title(run), Rgb{0, 0, 0}, 2);
        draw_text(image, x0 + 4, 24,
                  "whole map: F " + percent(run.whole.fscore) + ", Chamfer-L1 " +
                      centimetres(run.whole.chamfer_l1_m),
                  Rgb{40, 40, 40}, 2);
        render_mesh(image, x0, title_h, panel_w, panel_h, run.mesh, whole_view,
                    error_colours(run.mesh, reference_points));
        draw_rect(image, x0, title_h, x0 + panel_w - 1, title_h + panel_h - 1, Rgb{180, 180, 180});
        // Row 2: close-up of the early region.
        const int y1 = title_h + panel_h + gap;
        draw_text(image, x0 + 4, y1 + 4,
                  "first quarter: F " + percent(run.early.fscore) + ", Chamfer-L1 " +
                      centimetres(run.early.chamfer_l1_m),
                  Rgb{40, 40, 40}, 2);
        const TriangleMesh local = crop_to_box(run.mesh, close_up);
        render_mesh(image, x0, y1 + title_h, panel_w, panel_h, local, close_view,
                    error_colours(local, reference_points));
        draw_rect(image, x0, y1 + title_h, x0 + panel_w - 1, y1 + title_h + panel_h - 1,
                  Rgb{180, 180, 180});
    }
    // Legend: the colour scale.
    const int ly = image.height() - legend_h + 8;
    const int lx = gap + 4, lw = 300;
    for (int i = 0; i < lw; ++i) {
        fill_rect(image, lx + i, ly, lx + i, ly + 14,
                  error_colour(kErrorScaleM * i / lw, kErrorScaleM));
    }
    draw_text(image, lx + lw + 10, ly, "distance to the observed reference: 0 .. 10 cm and more",
              Rgb{40, 40, 40}, 2);
    image.write_png(path);
}

}  // namespace
}  // namespace forgetting_internal

ForgettingReport run_forgetting_experiment(const ForgettingConfig& config_in,
                                           const ScanSequence& sequence,
                                           const TriangleMesh& reference, const fs::path& out_dir) {
    using namespace forgetting_internal;
    ForgettingConfig config = config_in;
    config.mapper.finalize();
    const float lambda = config.mapper.incremental.importance.regularization_weight;
    if (!(lambda > 0.0f)) {
        throw ConfigError(
            "the forgetting experiment compares lambda_r > 0 with lambda_r = 0; set "
            "incremental.regularization_weight to a positive value");
    }
    if (!(config.early_fraction > 0.0 && config.early_fraction <= 1.0)) {
        throw ConfigError("early_fraction must be in (0, 1]");
    }
    if (sequence.size() == 0) throw DataError("the sequence has no scans");
    ensure_directory(out_dir);

    ForgettingReport report;
    report.frames = sequence.size();
    report.early_frames = std::max<std::size_t>(
        1, static_cast<std::size_t>(std::ceil(config.early_fraction * sequence.size())));
    report.threads = static_cast<int>(
        tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
    Eigen::AlignedBox3f sensor_box;
    const VoxelRegion region = early_region(sequence, report.early_frames, config.mapper.preprocess,
                                            config.region_voxel_m, sensor_box);
    const TriangleMesh early_reference = restrict_observed(reference, region);
    const VoxelRegion prediction_region = region.dilated(1);
    report.early_reference_area_m2 =
        mesh_surface_area_m2(early_reference, FaceSelection::kObserved);

    const auto evaluate = [&](ForgettingRun& run) {
        run.whole = evaluate_meshes(run.mesh, reference, config.eval);
        run.early =
            evaluate_meshes(crop_mesh(run.mesh, prediction_region), early_reference, config.eval);
    };
    for (const float weight : {0.0f, lambda}) {
        ForgettingRun run;
        run.name = weight > 0.0f ? "regularized" : "unregularized";
        run.regularization_weight = weight;
        MapperConfig mapper_config = config.mapper;
        mapper_config.incremental.importance.regularization_weight = weight;
        // The experiment measures what scan-by-scan training forgets: no consolidation at the
        // end unless asked for (it trains the kept scans again).
        if (!mapper_config.is_set("incremental.consolidation_steps")) {
            mapper_config.incremental.consolidation_steps = 0;
        }
        const auto start = std::chrono::steady_clock::now();
        IncrementalSequenceMap mapped =
            map_sequence_incremental(mapper_config, sequence, out_dir / run.name, run.name);
        run.seconds = seconds_since(start);
        run.median_frame_seconds = mapped.mapper->median_frame_seconds();
        run.map_bytes = mapped.mapper->sdf().memory_bytes();
        run.mesh = read_ply_mesh(out_dir / run.name / "mesh.ply");
        evaluate(run);
        report.runs.push_back(std::move(run));
    }
    if (config.with_batch) {
        ForgettingRun run;
        run.name = "batch";
        const auto start = std::chrono::steady_clock::now();
        SequenceMap mapped = map_sequence(config.mapper, sequence, out_dir / "batch", "batch");
        run.seconds = seconds_since(start);
        run.map_bytes = mapped.mapper->sdf().memory_bytes();
        run.mesh = read_ply_mesh(out_dir / "batch" / "mesh.ply");
        evaluate(run);
        report.runs.push_back(std::move(run));
    }

    Eigen::AlignedBox3f close_up = sensor_box;
    close_up.min() -= Eigen::Vector3f(kCloseUpMarginM, kCloseUpMarginM, 3.0f);
    close_up.max() += Eigen::Vector3f(kCloseUpMarginM, kCloseUpMarginM, 12.0f);
    write_figure(report, reference, close_up, config.image_panel_width, out_dir / "forgetting.png");
    const std::string json = forgetting_report_json(report, config);
    write_stream_atomically(out_dir / "forgetting.json", [&](std::ostream& out) { out << json; });
    return report;
}

std::string forgetting_report_json(const ForgettingReport& report, const ForgettingConfig& config) {
    nlohmann::json j;
    j["frames"] = report.frames;
    j["early_frames"] = report.early_frames;
    j["early_fraction"] = config.early_fraction;
    j["region_voxel_m"] = config.region_voxel_m;
    j["early_reference_area_m2"] = report.early_reference_area_m2;
    j["threads"] = report.threads;
    j["leaf_size_m"] = config.mapper.octree.leaf_size_m;
    j["iterations_per_frame"] = config.mapper.incremental.iterations_per_frame;
    j["replay_frames"] = config.mapper.incremental.replay_frames;
    j["importance_cap"] = config.mapper.incremental.importance.importance_cap;
    j["decoder_weights"] = config.mapper.incremental.decoder_weights;
    j["runs"] = nlohmann::json::array();
    for (const ForgettingRun& run : report.runs) {
        j["runs"].push_back({{"name", run.name},
                             {"regularization_weight", run.regularization_weight},
                             {"median_seconds_per_frame", run.median_frame_seconds},
                             {"seconds", run.seconds},
                             {"map_bytes", run.map_bytes},
                             {"whole", nlohmann::json::parse(metrics_to_json(run.whole))},
                             {"early", nlohmann::json::parse(metrics_to_json(run.early))}});
    }
    return j.dump(2) + "\n";
}

std::string format_forgetting_report(const ForgettingReport& report) {
    std::string out;
    char line[256];
    std::snprintf(line, sizeof(line),
                  "%zu frames; early region = what frames 0..%zu saw (%.0f m^2 of observed "
                  "reference); %d threads\n",
                  report.frames, report.early_frames - 1, report.early_reference_area_m2,
                  report.threads);
    out += line;
    std::snprintf(line, sizeof(line), "%-14s %-6s %9s %9s %9s %8s %8s %8s %10s\n", "run", "region",
                  "accuracy", "complet.", "Chamfer", "prec.", "recall", "F-score", "s/frame");
    out += line;
    for (const ForgettingRun& run : report.runs) {
        for (int r = 0; r < 2; ++r) {
            const MeshMetrics& m = r == 0 ? run.whole : run.early;
            char per_frame[32] = "         -";  // batch mode has no per-frame time
            if (run.median_frame_seconds > 0.0) {
                std::snprintf(per_frame, sizeof(per_frame), "%10.3f", run.median_frame_seconds);
            }
            std::snprintf(line, sizeof(line),
                          "%-14s %-6s %6.2f cm %6.2f cm %6.2f cm %7.2f%% %7.2f%% %7.2f%% %s\n",
                          run.name.c_str(), r == 0 ? "whole" : "early", 100 * m.accuracy_m,
                          100 * m.completion_m, 100 * m.chamfer_l1_m, 100 * m.precision,
                          100 * m.completion_ratio, 100 * m.fscore, per_frame);
            out += line;
        }
    }
    return out;
}

}  // namespace shine
