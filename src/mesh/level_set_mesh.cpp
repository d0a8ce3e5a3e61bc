#include "shine/mesh/level_set_mesh.hpp"

#include <openvdb/tools/VolumeToMesh.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <numeric>
#include <unordered_map>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/io/ply.hpp"

namespace shine {
namespace {
Eigen::Vector3d grid_origin_world_m(const openvdb::FloatGrid& level_set);
}  // namespace

TriangleMesh mesh_level_set(const openvdb::FloatGrid& level_set, const MeshConfig& config) {
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
    openvdb::tools::volumeToMesh(level_set, points, triangles, quads, config.isovalue_m,
                                 config.adaptivity);
    TriangleMesh mesh;
    // Grids baked by ShineVDB are in the map frame and name its world position.
    mesh.origin_world_m = grid_origin_world_m(level_set);
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

namespace {

Eigen::Vector3d grid_origin_world_m(const openvdb::FloatGrid& level_set) {
    if (const auto origin = level_set.getMetadata<openvdb::Vec3DMetadata>(kOriginMetadataKey)) {
        const openvdb::Vec3d& o = origin->value();
        return Eigen::Vector3d(o.x(), o.y(), o.z());
    }
    return Eigen::Vector3d::Zero();
}

/// The part of `level_set` within `box` (leaf-aligned), leaves and tiles copied, background
/// elsewhere; same transform and class.
openvdb::FloatGrid::Ptr cut_region(const openvdb::FloatGrid& level_set,
                                   const openvdb::CoordBBox& box) {
    using LeafT = openvdb::FloatTree::LeafNodeType;
    constexpr int kLeaf = static_cast<int>(LeafT::DIM);
    const openvdb::FloatTree& tree = level_set.tree();
    const float background = tree.background();
    auto region = openvdb::FloatGrid::create(background);
    region->setTransform(level_set.transform().copy());
    region->setGridClass(level_set.getGridClass());  // volumeToMesh orients polygons by it
    openvdb::FloatTree& out = region->tree();
    for (int x = box.min().x(); x <= box.max().x(); x += kLeaf) {
        for (int y = box.min().y(); y <= box.max().y(); y += kLeaf) {
            for (int z = box.min().z(); z <= box.max().z(); z += kLeaf) {
                const openvdb::Coord origin(x, y, z);
                if (const LeafT* leaf = tree.probeConstLeaf(origin)) {
                    out.addLeaf(new LeafT(*leaf));
                    continue;
                }
                float value = background;
                const bool active = tree.probeValue(origin, value);
                if (active || value != background) out.addTile(1, origin, value, active);
            }
        }
    }
    return region;
}

/// Welds the vertices that regions share: those within a voxel of a region's faces, keyed by
/// their exact coordinates (a shared vertex is computed from the same eight voxels in both
/// regions, so it is bit-identical).
class SeamVertices {
  public:
    /// The index of `v` if it was added before, else -1.
    std::int32_t find(const openvdb::Vec3s& v) const {
        const auto it = index_.find(key(v));
        return it == index_.end() ? -1 : it->second;
    }
    void add(const openvdb::Vec3s& v, std::int32_t index) { index_.emplace(key(v), index); }

  private:
    struct Key {
        std::uint32_t bits[3];
        bool operator==(const Key& o) const {
            return bits[0] == o.bits[0] && bits[1] == o.bits[1] && bits[2] == o.bits[2];
        }
    };
    struct Hash {
        std::size_t operator()(const Key& k) const {
            std::uint64_t h = 1469598103934665603ull;
            for (const std::uint32_t b : k.bits) h = (h ^ b) * 1099511628211ull;
            return static_cast<std::size_t>(h ^ (h >> 29));
        }
    };
    static Key key(const openvdb::Vec3s& v) {
        Key k;
        for (int a = 0; a < 3; ++a) {
            const float c = v[a];
            std::memcpy(&k.bits[a], &c, sizeof(float));
        }
        return k;
    }
    std::unordered_map<Key, std::int32_t, Hash> index_;
};

}  // namespace

MeshFileStats write_level_set_mesh(const openvdb::FloatGrid& level_set, const MeshConfig& config,
                                   const std::filesystem::path& path, int region_voxels,
                                   TriangleMesh* written) {
    using LeafT = openvdb::FloatTree::LeafNodeType;
    constexpr int kLeaf = static_cast<int>(LeafT::DIM);
    if (region_voxels < kLeaf || region_voxels % kLeaf != 0) {
        throw ConfigError("mesh region size must be a positive multiple of " +
                          std::to_string(kLeaf) + " voxels, got " + std::to_string(region_voxels));
    }
    MeshFileStats stats;
    if (config.adaptivity != 0.0 || config.min_component_triangles > 0) {
        TriangleMesh mesh = mesh_level_set(level_set, config);
        write_ply_mesh(path, mesh);
        stats.vertices = mesh.vertices.size();
        stats.triangles = mesh.triangles.size();
        stats.regions = 1;
        if (written) *written = std::move(mesh);
        return stats;
    }
    // Regions are columns, region_voxels square and as tall as the leaves reach (plus a leaf):
    // a seam across a column would run along the ground of a drive, where half the vertices are.
    // Only columns that hold leaves are meshed (volumeToMesh meshes leaves).
    openvdb::CoordBBox leaf_box;
    level_set.tree().evalLeafBoundingBox(leaf_box);
    const int z_min = leaf_box.min().z() - kLeaf, z_max = leaf_box.max().z() + kLeaf;
    auto column_of = [&](const openvdb::Coord& c) {
        return std::make_pair(static_cast<int>(std::floor(double(c.x()) / region_voxels)),
                              static_cast<int>(std::floor(double(c.y()) / region_voxels)));
    };
    std::vector<std::pair<int, int>> regions;
    for (auto leaf = level_set.tree().cbeginLeaf(); leaf; ++leaf) {
        regions.push_back(column_of(leaf->origin()));
    }
    std::sort(regions.begin(), regions.end());
    regions.erase(std::unique(regions.begin(), regions.end()), regions.end());

    PlyMeshStreamWriter writer(path, grid_origin_world_m(level_set), written);
    SeamVertices seam;
    const openvdb::math::Transform& transform = level_set.transform();
    std::vector<openvdb::Vec3s> points;
    std::vector<openvdb::Vec3I> triangles;
    std::vector<openvdb::Vec4I> quads;
    std::vector<std::int32_t> global;
    for (const auto& [column_x, column_y] : regions) {
        const openvdb::Coord core_min(column_x * region_voxels, column_y * region_voxels, z_min);
        const openvdb::Coord core_max(core_min.x() + region_voxels - 1,
                                      core_min.y() + region_voxels - 1, z_max);
        // A polygon kept here (centre in the core) lies within a voxel of its edge, and its
        // vertices depend on voxels at most two further out: one leaf of margin holds them all.
        const openvdb::CoordBBox cut(core_min.offsetBy(-kLeaf), core_max.offsetBy(kLeaf));
        const openvdb::FloatGrid::Ptr region = cut_region(level_set, cut);
        points.clear();
        triangles.clear();
        quads.clear();
        openvdb::tools::volumeToMesh(*region, points, triangles, quads, config.isovalue_m, 0.0);
        global.assign(points.size(), -1);
        auto in_core = [&](const openvdb::Vec3d& centre_world) {
            const openvdb::Vec3d index = transform.worldToIndex(centre_world);
            for (int a = 0; a < 3; ++a) {
                const double i = std::floor(index[a]);
                if (i < core_min[a] || i > core_max[a]) return false;
            }
            return true;
        };
        auto vertex = [&](unsigned local) {
            std::int32_t& g = global[local];
            if (g >= 0) return g;
            const openvdb::Vec3s& p = points[local];
            const openvdb::Vec3d index = transform.worldToIndex(openvdb::Vec3d(p));
            bool on_seam = false;
            for (int a = 0; a < 2; ++a) {
                on_seam = on_seam || index[a] <= core_min[a] + 1.0 || index[a] >= core_max[a];
            }
            if (on_seam) g = seam.find(p);
            if (g < 0) {
                g = writer.add_vertex(Eigen::Vector3f(p.x(), p.y(), p.z()));
                if (on_seam) seam.add(p, g);
            }
            return g;
        };
        // Same winding as mesh_level_set: OpenVDB's order reversed.
        for (const openvdb::Vec3I& t : triangles) {
            const openvdb::Vec3d centre =
                (openvdb::Vec3d(points[t[0]]) + openvdb::Vec3d(points[t[1]]) +
                 openvdb::Vec3d(points[t[2]])) /
                3.0;
            if (!in_core(centre)) continue;
            writer.add_triangle(vertex(t[2]), vertex(t[1]), vertex(t[0]));
        }
        for (const openvdb::Vec4I& q : quads) {
            const openvdb::Vec3d centre =
                (openvdb::Vec3d(points[q[0]]) + openvdb::Vec3d(points[q[1]]) +
                 openvdb::Vec3d(points[q[2]]) + openvdb::Vec3d(points[q[3]])) *
                0.25;
            if (!in_core(centre)) continue;
            const std::int32_t v0 = vertex(q[0]), v1 = vertex(q[1]), v2 = vertex(q[2]),
                               v3 = vertex(q[3]);
            writer.add_triangle(v2, v1, v0);
            writer.add_triangle(v3, v2, v0);
        }
    }
    writer.commit();
    stats.vertices = writer.num_vertices();
    stats.triangles = writer.num_triangles();
    stats.regions = regions.size();
    return stats;
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
