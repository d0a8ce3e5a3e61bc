// `shine bake MAP -o surface.vdb` and `shine mesh INPUT -o mesh.ply`: re-create the surface and
// the mesh from a saved map, at another resolution if asked.
#include <cstdio>
#include <filesystem>

#include "cli_common.hpp"
#include "command_registry.hpp"
#include "shine/bake/level_set_bake.hpp"
#include "shine/bake/level_set_file.hpp"
#include "shine/core/error.hpp"
#include "shine/io/ply.hpp"
#include "shine/mapper/mapper_config.hpp"
#include "shine/mesh/level_set_mesh.hpp"
#include "shine/model/map_file.hpp"

namespace shine::cli {
namespace {
namespace fs = std::filesystem;

struct BakeOptions {
    std::string input;
    std::string out;
    double voxel_size_m = 0.0;
    float half_width_voxels = 3.0f;
    int mask_level = -1;
    int threads = 0;
    double adaptivity = 0.0;
};

/// Bake settings: those stored in the map unless overridden on the command line.
BakeConfig bake_config_for(const LoadedMap& map, const BakeOptions& opt) {
    MapperConfig stored;
    parse_config_yaml(map.config_text, "map.vdb configuration", stored);
    BakeConfig bake = stored.bake;
    if (opt.voxel_size_m != 0.0) {
        if (!(opt.voxel_size_m > 0.0)) throw ConfigError("--voxel-size-m must be positive");
        bake.voxel_size_m = opt.voxel_size_m;
    }
    bake.half_width_voxels = opt.half_width_voxels;
    if (opt.mask_level >= 0) bake.mask_level = opt.mask_level;
    return bake;
}

/// The level set of `input`: read from a surface .vdb, or baked from a neural map .vdb.
openvdb::FloatGrid::Ptr level_set_from(const BakeOptions& opt) {
    openvdb::initialize();
    // A surface .vdb is used as it is unless a new resolution or mask is asked for; anything
    // else must be a neural map, whose loader explains what is wrong with the file.
    if (opt.voxel_size_m == 0.0 && opt.mask_level < 0) {
        try {
            return read_level_set(opt.input);
        } catch (const IoError&) {
        }
    }
    const LoadedMap map = load_neural_map(opt.input);
    BakeStats stats;
    auto grid = bake_level_set(map.sdf, bake_config_for(map, opt), &stats);
    std::fprintf(stderr, "baked %zu active voxels at %.3f m\n", stats.active_voxels,
                 stats.voxel_size_m);
    return grid;
}

int run_bake(const BakeOptions& opt) {
    auto threads = limit_threads(opt.threads);
    const LoadedMap map = load_neural_map(opt.input);
    BakeStats stats;
    auto grid = bake_level_set(map.sdf, bake_config_for(map, opt), &stats);
    write_level_set(opt.out, grid);
    std::printf("wrote %s: %zu active voxels at %.3f m\n", opt.out.c_str(), stats.active_voxels,
                stats.voxel_size_m);
    return 0;
}

int run_mesh(const BakeOptions& opt) {
    auto threads = limit_threads(opt.threads);
    auto grid = level_set_from(opt);
    MeshConfig mesh_config;
    mesh_config.adaptivity = opt.adaptivity;
    const MeshFileStats mesh = write_level_set_mesh(*grid, mesh_config, opt.out);
    std::printf("wrote %s: %zu vertices, %zu triangles\n", opt.out.c_str(), mesh.vertices,
                mesh.triangles);
    return 0;
}

void add_common(CLI::App* cmd, BakeOptions& opt) {
    cmd->add_option("--voxel-size-m", opt.voxel_size_m,
                    "Level-set voxel size in metres (default: the map's setting, half the leaf)");
    cmd->add_option("--half-width-voxels", opt.half_width_voxels, "Narrow-band half-width")
        ->capture_default_str();
    cmd->add_option("--mask-level", opt.mask_level,
                    "Bake inside the allocated cells of this level (default: the map's setting)");
    cmd->add_option("--threads", opt.threads, "Worker threads (0 = all cores)");
}

const RegisterCommand kRegisterBake(30, [](CLI::App& app, Action& action) {
    auto opt = std::make_shared<BakeOptions>();
    CLI::App* cmd = app.add_subcommand("bake", "Bake a neural map (map.vdb) into a level set .vdb");
    cmd->add_option("map", opt->input, "Neural map .vdb")->required();
    cmd->add_option("-o,--output", opt->out, "Output level set .vdb")->required();
    add_common(cmd, *opt);
    cmd->callback([opt, &action] { action = [opt] { return run_bake(*opt); }; });
});

const RegisterCommand kRegisterMesh(40, [](CLI::App& app, Action& action) {
    auto opt = std::make_shared<BakeOptions>();
    CLI::App* cmd = app.add_subcommand(
        "mesh", "Mesh a level set (surface.vdb), or a neural map (map.vdb) baked on the fly");
    cmd->add_option("input", opt->input, "surface.vdb or map.vdb")->required();
    cmd->add_option("-o,--output", opt->out, "Output mesh .ply")->required();
    cmd->add_option("--adaptivity", opt->adaptivity, "Mesh decimation in [0, 1]")
        ->capture_default_str();
    add_common(cmd, *opt);
    cmd->callback([opt, &action] { action = [opt] { return run_mesh(*opt); }; });
});

}  // namespace
}  // namespace shine::cli
