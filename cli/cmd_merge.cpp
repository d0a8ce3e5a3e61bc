// `shine merge`: tile maps (each mapped from the scans that see its core box grown by an overlap,
// all with the same origin and frozen decoder) -> one neural map, level set and mesh, with
// stats.json and metrics against a reference mesh when one is given (docs/tiles.md).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli_common.hpp"
#include "command_registry.hpp"
#include "product_stats.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/eval/mesh_metrics.hpp"
#include "shine/eval/metrics_report.hpp"
#include "shine/io/ply.hpp"
#include "shine/mapper/map_merge.hpp"
#include "shine/mapper/map_sequence.hpp"
#include "shine/mapper/mapper_config.hpp"
#include "shine/model/map_file.hpp"

namespace shine::cli {
namespace {
namespace fs = std::filesystem;

struct MergeOptions {
    std::vector<std::string> tiles;  ///< PATH:xmin,ymin,xmax,ymax
    std::string manifest;
    std::string out;
    std::string ref_path;
    int threads = 0;
};

/// The merged map's configuration: the first tile's (bake and mesh settings, origin) without its
/// crop box, which covered that tile only.
MapperConfig merged_config(const MergedMap& merged, const fs::path& first_tile, int threads) {
    MapperConfig config;
    parse_config_yaml(merged.first_tile_config_text,
                      "the configuration stored in '" + first_tile.string() + "'", config);
    config.crop_world_m.clear();
    config.threads = threads;
    config.finalize();
    return config;
}

nlohmann::json bound_json(double v) {
    if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
    return v;
}

int run_merge(const MergeOptions& opt) {
    const auto start = std::chrono::steady_clock::now();
    if (opt.tiles.empty() == opt.manifest.empty()) {
        throw ConfigError(
            "give the tiles either as --tile PATH:xmin,ymin,xmax,ymax (repeated) or as "
            "--manifest FILE, not both and not neither");
    }
    std::vector<MapTile> tiles;
    if (!opt.manifest.empty()) {
        tiles = read_tile_manifest(opt.manifest);
    } else {
        for (const std::string& spec : opt.tiles) tiles.push_back(parse_tile_spec(spec));
    }
    if (!opt.ref_path.empty() && !fs::is_regular_file(opt.ref_path)) {
        throw IoError("reference mesh '" + opt.ref_path + "' does not exist");
    }
    auto threads = limit_threads(opt.threads);
    const fs::path out = opt.out;

    const MergedMap merged = merge_tile_maps(tiles);
    const double merge_seconds = seconds_since(start);
    const MapperConfig config = merged_config(merged, tiles[0].map_path, opt.threads);
    ensure_directory(out);
    const MapProducts products = write_map_products(merged.sdf, config, out);

    const NeuralSdf& sdf = merged.sdf;
    nlohmann::json tiles_json = nlohmann::json::array();
    for (std::size_t i = 0; i < tiles.size(); ++i) {
        const TileCore& c = tiles[i].core_world_m;
        tiles_json.push_back({{"map", tiles[i].map_path.string()},
                              {"core_world_m",
                               {bound_json(c.x_min_m), bound_json(c.y_min_m), bound_json(c.x_max_m),
                                bound_json(c.y_max_m)}},
                              {"corners", merged.stats.tiles[i].corners},
                              {"corners_taken", merged.stats.tiles[i].corners_taken}});
    }
    nlohmann::json json;
    json["mode"] = "merge";
    json["tiles"] = tiles_json;
    json["origin_world_m"] = {sdf.origin_world_m.x(), sdf.origin_world_m.y(),
                              sdf.origin_world_m.z()};
    json["leaf_size_m"] = sdf.octree.config().leaf_size_m;
    json["fallback_corners"] = merged.stats.fallback_corners;
    add_product_stats(json, sdf, products, out);
    json["seconds"] = {{"merge", merge_seconds},
                       {"save_map", products.save_seconds},
                       {"bake", products.bake_seconds},
                       {"mesh", products.mesh_seconds}};

    std::printf(
        "merged %zu tiles into %zu corners (%zu from a neighbour of their owner tile), "
        "map %.2f MB\n",
        tiles.size(), sdf.octree.num_corners(), merged.stats.fallback_corners,
        sdf.memory_bytes() / 1e6);
    std::printf("wrote %s, %s, %s (%zu triangles)\n", (out / "map.vdb").c_str(),
                (out / "surface.vdb").c_str(), (out / "mesh.ply").c_str(), products.mesh.triangles);
    if (!opt.ref_path.empty()) {
        const auto t0 = std::chrono::steady_clock::now();
        const MeshMetrics metrics =
            evaluate_meshes(read_ply_mesh(out / "mesh.ply"), read_ply_mesh(opt.ref_path));
        json["eval"] = nlohmann::json::parse(metrics_to_json(metrics));
        json["eval"]["reference"] = opt.ref_path;
        json["seconds"]["eval"] = seconds_since(t0);
        std::printf("accuracy against %s:\n%s", opt.ref_path.c_str(),
                    format_metrics(metrics).c_str());
    }
    json["seconds"]["total"] = seconds_since(start);
    json["peak_rss_bytes"] = peak_rss_bytes();
    write_stream_atomically(out / "stats.json",
                            [&](std::ostream& os) { os << json.dump(2) << "\n"; });
    return 0;
}

const RegisterCommand kRegisterMerge(65, [](CLI::App& app, Action& action) {
    auto opt = std::make_shared<MergeOptions>();
    CLI::App* cmd = app.add_subcommand(
        "merge",
        "Merge tile maps (same origin and frozen decoder, e.g. from scripts/shine_dask_tiles.py) "
        "into one OUT/map.vdb, surface.vdb, mesh.ply, stats.json; each corner's feature comes "
        "from the tile whose core box contains it (docs/tiles.md)");
    cmd->add_option("--tile", opt->tiles,
                    "A tile: PATH/map.vdb:xmin,ymin,xmax,ymax (its core box in world metres, "
                    "half-open; the cores partition the plane); repeat for every tile");
    cmd->add_option("--manifest", opt->manifest,
                    "JSON or YAML file {\"tiles\": [{\"map\": PATH, \"core_world_m\": [xmin, ymin, "
                    "xmax, ymax]}, ...]} (paths relative to the file), instead of --tile");
    cmd->add_option("-o,--output", opt->out, "Output directory")->required();
    cmd->add_option("--ref", opt->ref_path, "Reference mesh (PLY) to evaluate the merged mesh");
    cmd->add_option("--threads", opt->threads, "Worker threads (0 = all cores)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    cmd->callback([opt, &action] { action = [opt] { return run_merge(*opt); }; });
});

}  // namespace
}  // namespace shine::cli
