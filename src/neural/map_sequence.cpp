#include "shine/mapper/map_sequence.hpp"

#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cstdio>

#include "shine/bake/level_set_file.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/progress.hpp"
#include "shine/io/ply.hpp"
#include "shine/map/map_file.hpp"
#include "shine/mesh/level_set_mesh.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace {
double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string tagged(const std::string& label, const std::string& tag) {
    return tag.empty() ? label : label + " " + tag;
}
}  // namespace

void train_with_progress(BatchMapper& mapper, int iterations, const std::string& label) {
    Progress progress(label, static_cast<std::size_t>(std::max(iterations, 0)));
    mapper.train([&](std::size_t done, double bce) {
        char detail[64];
        std::snprintf(detail, sizeof(detail), "bce %.4f", bce);
        progress.update(done, detail);
    });
    progress.finish();
}

MapProducts write_map_products(const NeuralSdf& sdf, const MapperConfig& config,
                               const fs::path& out_dir) {
    MapProducts products;
    const std::string config_yaml = config_to_yaml(config);
    auto t0 = std::chrono::steady_clock::now();
    save_neural_map(out_dir / "map.vdb", sdf, config_yaml);
    products.save_seconds = seconds_since(t0);

    t0 = std::chrono::steady_clock::now();
    auto surface = bake_level_set(sdf, config.bake, &products.bake);
    write_level_set(out_dir / "surface.vdb", surface);
    products.bake_seconds = seconds_since(t0);
    products.surface_mem_bytes = surface->memUsage();

    t0 = std::chrono::steady_clock::now();
    products.mesh = mesh_level_set(*surface, config.mesh);
    write_ply_mesh(out_dir / "mesh.ply", products.mesh);
    products.mesh_seconds = seconds_since(t0);
    return products;
}

SequenceMap map_sequence(const MapperConfig& config_in, const ScanSequence& sequence,
                         const fs::path& out_dir, const std::string& progress_tag) {
    MapperConfig config = config_in;
    config.finalize();
    ensure_directory(out_dir);
    SequenceMap result;
    result.mapper = std::make_unique<BatchMapper>(config);
    BatchMapper& mapper = *result.mapper;
    {
        Progress progress(tagged("load", progress_tag), sequence.size());
        for (std::size_t i = 0; i < sequence.size(); ++i) {
            const auto t0 = std::chrono::steady_clock::now();
            const Scan scan = sequence.load(i);
            const double load_seconds = seconds_since(t0);
            StageSeconds stages = mapper.add_scan(scan);
            stages[Stage::kLoad] = load_seconds;
            result.profile.frames.push_back(stages);
            progress.update(i + 1, std::to_string(mapper.sdf().octree.num_corners()) + " corners");
        }
        progress.finish(std::to_string(mapper.stats().rays) + " rays, " +
                        std::to_string(mapper.sdf().octree.num_corners()) + " corners");
    }
    train_with_progress(mapper, config.batch_iterations(), tagged("train", progress_tag));
    result.products = write_map_products(mapper.sdf(), config, out_dir);
    const MappingStats& stats = mapper.stats();
    StageProfile& profile = result.profile;
    profile.threads = static_cast<int>(
        tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
    profile.run = product_stages(result.products);
    profile.run[Stage::kNormals] = stats.normals_seconds;
    profile.run[Stage::kSample] = stats.sample_seconds;
    profile.run[Stage::kTrain] = stats.train_seconds - stats.sample_seconds;
    return result;
}

StageSeconds product_stages(const MapProducts& products) {
    StageSeconds stages;
    stages[Stage::kBake] = products.bake_seconds;
    stages[Stage::kMesh] = products.mesh_seconds;
    return stages;
}

}  // namespace shine
