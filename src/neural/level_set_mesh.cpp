#include "shine/mesh/level_set_mesh.hpp"

#include <openvdb/tools/VolumeToMesh.h>

#include <numeric>

namespace shine {

TriangleMesh mesh_level_set(const openvdb::FloatGrid& level_set, const MeshConfig& config) {
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(level_set, points, triangles, quads, config.isovalue_m,
                                 config.adaptivity);
    TriangleMesh mesh;
    // Grids baked by ShineVDB are in the map frame and name its world position.
    if (const auto origin = level_set.getMetadata<openvdb::Vec3DMetadata>(kOriginMetadataKey)) {
        const openvdb::Vec3d& o = origin->value();
        mesh.origin_world_m = Eigen::Vector3d(o.x(), o.y(), o.z());
    }
    mesh.vertices.reserve(points.size());
    for (const auto& p : points) mesh.vertices.emplace_back(p.x(), p.y(), p.z());
    mesh.triangles.reserve(triangles.size() + 2 * quads.size());
    // OpenVDB orders polygons for an outward normal on its level sets (negative inside); PLY
    // viewers expect counter-clockwise front faces, which is the reverse order.
    for (const auto& t : triangles) mesh.triangles.emplace_back(t[2], t[1], t[0]);
    for (const auto& q : quads) {
        mesh.triangles.emplace_back(q[2], q[1], q[0]);
        mesh.triangles.emplace_back(q[3], q[2], q[0]);
    }
    if (config.min_component_triangles > 0) {
        remove_small_components(mesh, config.min_component_triangles);
    }
    return mesh;
}

std::size_t remove_small_components(TriangleMesh& mesh, std::size_t min_triangles) {
    // Union-find over vertices joined by triangles.
    std::vector<int> parent(mesh.vertices.size());
    std::iota(parent.begin(), parent.end(), 0);
    auto find = [&](int v) {
        while (parent[v] != v) v = parent[v] = parent[parent[v]];
        return v;
    };
    for (const auto& t : mesh.triangles) {
        const int a = find(t[0]), b = find(t[1]), c = find(t[2]);
        parent[b] = a;
        parent[find(c)] = find(a);
    }
    std::vector<std::size_t> count(mesh.vertices.size(), 0);
    for (const auto& t : mesh.triangles) ++count[find(t[0])];
    std::vector<Eigen::Vector3i> kept;
    kept.reserve(mesh.triangles.size());
    for (const auto& t : mesh.triangles) {
        if (count[find(t[0])] >= min_triangles) kept.push_back(t);
    }
    const std::size_t removed = mesh.triangles.size() - kept.size();
    // Compact the vertices.
    std::vector<int> remap(mesh.vertices.size(), -1);
    std::vector<Eigen::Vector3f> vertices;
    for (auto& t : kept) {
        for (int i = 0; i < 3; ++i) {
            int& r = remap[t[i]];
            if (r < 0) {
                r = static_cast<int>(vertices.size());
                vertices.push_back(mesh.vertices[t[i]]);
            }
            t[i] = r;
        }
    }
    mesh.vertices = std::move(vertices);
    mesh.triangles = std::move(kept);
    mesh.face_observed.clear();
    return removed;
}

}  // namespace shine
