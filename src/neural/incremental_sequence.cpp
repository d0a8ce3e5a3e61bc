#include "shine/mapper/incremental_sequence.hpp"

#include <tbb/global_control.h>

#include <chrono>
#include <cstdio>

#include "shine/core/atomic_file.hpp"
#include "shine/core/progress.hpp"
#include "shine/io/ply.hpp"
#include "shine/mesh/level_set_mesh.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace {
double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string frame_name(std::size_t frame) {
    char name[32];
    std::snprintf(name, sizeof(name), "mesh_%06zu.ply", frame);
    return name;
}
}  // namespace

IncrementalSequenceMap map_sequence_incremental(const MapperConfig& config_in,
                                                const ScanSequence& sequence,
                                                const fs::path& out_dir,
                                                const std::string& progress_tag) {
    MapperConfig config = config_in;
    config.finalize();
    ensure_directory(out_dir);
    const int mesh_every = config.incremental.mesh_every;
    if (mesh_every > 0) ensure_directory(out_dir / "progress");
    IncrementalSequenceMap result;
    result.mapper = std::make_unique<IncrementalMapper>(config);
    IncrementalMapper& mapper = *result.mapper;
    {
        Progress progress(progress_tag.empty() ? "map" : "map " + progress_tag, sequence.size());
        for (std::size_t i = 0; i < sequence.size(); ++i) {
            const auto t_load = std::chrono::steady_clock::now();
            const Scan scan = sequence.load(i);
            const double load_seconds = seconds_since(t_load);
            const IncrementalFrameStats& frame = mapper.add_scan(scan);
            StageSeconds stages = frame.stages;
            stages[Stage::kLoad] = load_seconds;
            result.profile.frames.push_back(stages);
            char detail[96];
            std::snprintf(detail, sizeof(detail), "%.2f s/frame, bce %.4f, %zu corners",
                          frame.total_seconds, frame.bce, mapper.sdf().octree.num_corners());
            progress.update(i + 1, detail);
            const bool last = i + 1 == sequence.size();
            if (mesh_every > 0 && ((i + 1) % static_cast<std::size_t>(mesh_every) == 0) && !last) {
                ProgressMesh snapshot;
                snapshot.frame = i;
                auto t0 = std::chrono::steady_clock::now();
                const auto surface = bake_level_set(mapper.sdf(), config.bake);
                const TriangleMesh mesh = mesh_level_set(*surface, config.mesh);
                snapshot.bake_seconds = seconds_since(t0);
                t0 = std::chrono::steady_clock::now();
                snapshot.path = out_dir / "progress" / frame_name(i);
                write_ply_mesh(snapshot.path, mesh);
                snapshot.write_seconds = seconds_since(t0);
                snapshot.triangles = mesh.triangles.size();
                result.progress_meshes.push_back(snapshot);
            }
        }
        char detail[64];
        std::snprintf(detail, sizeof(detail), "median %.2f s/frame", mapper.median_frame_seconds());
        progress.finish(detail);
    }
    result.products = write_map_products(mapper.sdf(), config, out_dir);
    result.profile.threads = static_cast<int>(
        tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
    result.profile.run = product_stages(result.products);
    if (mesh_every > 0 && sequence.size() > 0) {
        // The final mesh is the last progress mesh too, so the series ends with the whole run.
        const auto t0 = std::chrono::steady_clock::now();
        ProgressMesh snapshot;
        snapshot.frame = sequence.size() - 1;
        snapshot.path = out_dir / "progress" / frame_name(snapshot.frame);
        write_ply_mesh(snapshot.path, result.products.mesh);
        snapshot.write_seconds = seconds_since(t0);
        snapshot.bake_seconds = result.products.bake_seconds + result.products.mesh_seconds;
        snapshot.triangles = result.products.mesh.triangles.size();
        result.progress_meshes.push_back(snapshot);
    }
    return result;
}

}  // namespace shine
