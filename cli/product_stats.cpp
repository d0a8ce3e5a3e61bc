#include "product_stats.hpp"

#include "shine/model/map_file.hpp"

namespace shine::cli {

void add_product_stats(nlohmann::json& json, const NeuralSdf& sdf, const MapProducts& products,
                       const std::filesystem::path& out) {
    json["map"] = {{"corners", sdf.octree.num_corners()},
                   {"feature_precision", to_string(sdf.octree.feature_precision())},
                   {"feature_bytes", sdf.octree.feature_bytes()},
                   {"structure_bytes", sdf.octree.structure_bytes()},
                   {"decoder_bytes", sdf.decoder.num_params() * sizeof(float)},
                   {"map_bytes", sdf.memory_bytes()},
                   {"file_bytes", file_bytes(out / "map.vdb")}};
    json["surface"] = {{"voxel_size_m", products.bake.voxel_size_m},
                       {"active_voxels", products.bake.active_voxels},
                       {"mem_bytes", products.surface_mem_bytes},
                       {"file_bytes", file_bytes(out / "surface.vdb")}};
    json["mesh"] = {{"vertices", products.mesh.vertices},
                    {"triangles", products.mesh.triangles},
                    {"regions", products.mesh.regions}};
}

}  // namespace shine::cli
