#include "shine/tsdf/tsdf_mesh.hpp"

#include <openvdb/tree/LeafManager.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/tsdf/marching_cubes.hpp"

namespace shine {

void TsdfMeshConfig::validate() const {
    if (!(min_weight >= 0.0f) || !std::isfinite(min_weight)) {
        throw ConfigError("--min-weight = " + std::to_string(min_weight) +
                          " must be a finite number >= 0 (a voxel's weight counts its updates)");
    }
}

namespace tsdf_mesh_internal {
namespace {

/// A lattice edge: its lower corner and its axis.
struct EdgeKey {
    openvdb::Coord lower;
    int axis;
    bool operator==(const EdgeKey& o) const { return lower == o.lower && axis == o.axis; }
};

struct EdgeKeyHash {
    std::size_t operator()(const EdgeKey& k) const {
        std::uint64_t h = static_cast<std::uint32_t>(k.lower.x());
        h = h * 0x9E3779B97F4A7C15ull ^ static_cast<std::uint32_t>(k.lower.y());
        h = h * 0x9E3779B97F4A7C15ull ^ static_cast<std::uint32_t>(k.lower.z());
        h = h * 0x9E3779B97F4A7C15ull ^ static_cast<std::uint64_t>(k.axis);
        return static_cast<std::size_t>(h ^ (h >> 29));
    }
};

/// The part of the mesh made by the cubes of one leaf node, with leaf-local vertex indices.
struct LeafMesh {
    std::vector<EdgeKey> vertex_keys;
    std::vector<Eigen::Vector3f> vertices;
    std::vector<Eigen::Vector3i> triangles;
};

}  // namespace
}  // namespace tsdf_mesh_internal

TriangleMesh extract_tsdf_mesh(const TsdfVolume& volume, const TsdfMeshConfig& config) {
    using namespace tsdf_mesh_internal;
    config.validate();
    const auto& table = marching_cubes_table();
    const double voxel_m = volume.config().voxel_size_m;
    const openvdb::FloatTree& tsdf_tree = volume.tsdf_grid().tree();
    const openvdb::FloatTree& weight_tree = volume.weight_grid().tree();

    openvdb::tree::LeafManager<const openvdb::FloatTree> leaves(tsdf_tree);
    std::vector<LeafMesh> parts(leaves.leafCount());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, leaves.leafCount()), [&](const auto& r) {
        openvdb::tree::ValueAccessor<const openvdb::FloatTree> tsdf(tsdf_tree);
        openvdb::tree::ValueAccessor<const openvdb::FloatTree> weight(weight_tree);
        std::unordered_map<EdgeKey, int, EdgeKeyHash> local_index;
        for (std::size_t l = r.begin(); l != r.end(); ++l) {
            LeafMesh& part = parts[l];
            local_index.clear();
            for (auto it = leaves.leaf(l).cbeginValueOn(); it; ++it) {
                const openvdb::Coord v = it.getCoord();
                float value[8];
                int mask = 0;
                bool skip = false;
                for (int c = 0; c < 8 && !skip; ++c) {
                    const openvdb::Coord corner =
                        v.offsetBy(kCubeCorner[c][0], kCubeCorner[c][1], kCubeCorner[c][2]);
                    const float w = weight.getValue(corner);
                    // VDBFusion's two corner tests: unobserved (unless fill_holes), too light.
                    if ((!config.fill_holes && w == 0.0f) || w < config.min_weight) skip = true;
                    value[c] = tsdf.getValue(corner);
                    if (value[c] < 0.0f) mask |= 1 << c;
                }
                if (skip || mask == 0 || mask == 255) continue;
                const MarchingCubesCase& cube = table[mask];
                int vertex_of_edge[12];
                for (int e = 0; e < 12; ++e) {
                    if (!((cube.edge_mask >> e) & 1)) continue;
                    const int a = kCubeEdge[e][0], b = kCubeEdge[e][1];
                    const int axis = kCubeEdgeAxis[e];
                    const EdgeKey key{
                        v.offsetBy(kCubeCorner[a][0], kCubeCorner[a][1], kCubeCorner[a][2]), axis};
                    const auto [slot, inserted] =
                        local_index.try_emplace(key, static_cast<int>(part.vertices.size()));
                    vertex_of_edge[e] = slot->second;
                    if (!inserted) continue;
                    const double da = std::abs(static_cast<double>(value[a]));
                    const double db = std::abs(static_cast<double>(value[b]));
                    Eigen::Vector3d p(key.lower.x() + 0.5, key.lower.y() + 0.5,
                                      key.lower.z() + 0.5);
                    p[axis] += da / (da + db);
                    part.vertex_keys.push_back(key);
                    part.vertices.push_back((p * voxel_m).cast<float>());
                }
                for (const auto& t : cube.triangles) {
                    part.triangles.emplace_back(vertex_of_edge[t[0]], vertex_of_edge[t[1]],
                                                vertex_of_edge[t[2]]);
                }
            }
        }
    });

    // Merge in leaf order: a vertex on an edge shared with another leaf's cubes is kept once.
    // Vertices stay in the volume's map frame (float32 keeps millimetres there, not at UTM
    // coordinates); the mesh carries the frame's world position.
    TriangleMesh mesh;
    mesh.origin_world_m = volume.origin_world_m();
    std::size_t num_vertices = 0, num_triangles = 0;
    for (const auto& part : parts) {
        num_vertices += part.vertices.size();
        num_triangles += part.triangles.size();
    }
    std::unordered_map<EdgeKey, int, EdgeKeyHash> global_index;
    global_index.reserve(num_vertices);
    mesh.vertices.reserve(num_vertices);
    mesh.triangles.reserve(num_triangles);
    std::vector<int> remap;
    for (const auto& part : parts) {
        remap.resize(part.vertices.size());
        for (std::size_t i = 0; i < part.vertices.size(); ++i) {
            const auto [slot, inserted] = global_index.try_emplace(
                part.vertex_keys[i], static_cast<int>(mesh.vertices.size()));
            if (inserted) mesh.vertices.push_back(part.vertices[i]);
            remap[i] = slot->second;
        }
        for (const auto& t : part.triangles) {
            mesh.triangles.emplace_back(remap[t[0]], remap[t[1]], remap[t[2]]);
        }
    }
    return mesh;
}

}  // namespace shine
