// Writes the .vdb seeds of fuzz_vdb: a tiny neural map (map.vdb) and a tiny level set
// (surface.vdb), both a few kilobytes so that libFuzzer mutates every part of them.
//   make_vdb_seeds OUTPUT_DIR
#include <openvdb/tools/LevelSetSphere.h>

#include <cstdio>
#include <filesystem>

#include "shine/bake/level_set_file.hpp"
#include "shine/model/map_file.hpp"

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: %s OUTPUT_DIR\n", argv[0]);
        return 2;
    }
    const std::filesystem::path dir = argv[1];
    std::filesystem::create_directories(dir);
    openvdb::initialize();

    shine::FeatureOctreeConfig octree;
    octree.leaf_size_m = 1.0;
    octree.num_levels = 2;
    octree.feature_dim = 2;
    shine::DecoderConfig decoder;
    decoder.input_dim = octree.feature_dim;
    decoder.hidden_dims = {4};
    shine::NeuralSdf sdf(octree, decoder);
    // Inside one 8^3 leaf node of each level's grid, so that each grid holds a single leaf.
    sdf.octree.allocate_cells({Eigen::Vector3f(3.5f, 3.5f, 3.5f)});
    shine::save_neural_map(dir / "map.vdb", sdf, "map:\n  leaf_size_m: 1\n");

    // Radius 1.5 voxels of 1 m, narrow band of 2 voxels, inside the leaf node [0, 8)^3.
    const auto sphere = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
        1.5f, openvdb::Vec3f(4.0f), 1.0f, 2.0f);
    sphere->setName("surface");
    shine::write_level_set(dir / "surface.vdb", sphere);
    std::printf("wrote %s and %s\n", (dir / "map.vdb").c_str(), (dir / "surface.vdb").c_str());
    return 0;
}
