#include "shine/eval/region_crop.hpp"

#include <cmath>
#include <string>

#include "shine/core/error.hpp"

namespace shine {
namespace {
// Voxel coordinates are packed 21 bits per axis (offset so that they are non-negative): +-1M
// voxels, i.e. +-1000 km at 1 m voxels.
constexpr std::int64_t kBias = 1 << 20;
constexpr std::uint64_t kMask = (1u << 21) - 1;

std::uint64_t pack(std::int64_t x, std::int64_t y, std::int64_t z) {
    return (std::uint64_t(x + kBias) & kMask) | ((std::uint64_t(y + kBias) & kMask) << 21) |
           ((std::uint64_t(z + kBias) & kMask) << 42);
}
}  // namespace

VoxelRegion::VoxelRegion(double voxel_size_m) : voxel_size_m_(voxel_size_m) {
    if (!(voxel_size_m > 0.0) || !std::isfinite(voxel_size_m)) {
        throw ConfigError("region voxel size must be positive, got " +
                          std::to_string(voxel_size_m));
    }
}

std::uint64_t VoxelRegion::key(const Eigen::Vector3f& p) const {
    const double inv = 1.0 / voxel_size_m_;
    return pack(static_cast<std::int64_t>(std::floor(p.x() * inv)),
                static_cast<std::int64_t>(std::floor(p.y() * inv)),
                static_cast<std::int64_t>(std::floor(p.z() * inv)));
}

void VoxelRegion::add_points(const std::vector<Eigen::Vector3f>& points) {
    for (const auto& p : points) {
        if (p.allFinite()) voxels_.insert(key(p));
    }
}

VoxelRegion VoxelRegion::dilated(int voxels) const {
    VoxelRegion out(voxel_size_m_);
    for (const std::uint64_t k : voxels_) {
        const std::int64_t x = std::int64_t(k & kMask) - kBias;
        const std::int64_t y = std::int64_t((k >> 21) & kMask) - kBias;
        const std::int64_t z = std::int64_t((k >> 42) & kMask) - kBias;
        for (int dx = -voxels; dx <= voxels; ++dx) {
            for (int dy = -voxels; dy <= voxels; ++dy) {
                for (int dz = -voxels; dz <= voxels; ++dz) {
                    out.voxels_.insert(pack(x + dx, y + dy, z + dz));
                }
            }
        }
    }
    return out;
}

bool VoxelRegion::contains(const Eigen::Vector3f& point) const {
    return point.allFinite() && voxels_.count(key(point)) > 0;
}

double VoxelRegion::volume_m3() const {
    return static_cast<double>(voxels_.size()) * voxel_size_m_ * voxel_size_m_ * voxel_size_m_;
}

TriangleMesh extract_triangles(const TriangleMesh& mesh, const std::vector<std::uint32_t>& indices,
                               std::vector<int>& vertex_slot) {
    TriangleMesh out;
    out.origin_world_m = mesh.origin_world_m;
    const bool flags = mesh.face_observed.size() == mesh.triangles.size();
    out.triangles.reserve(indices.size());
    if (flags) out.face_observed.reserve(indices.size());
    for (const std::uint32_t i : indices) {
        const Eigen::Vector3i& t = mesh.triangles[i];
        Eigen::Vector3i renumbered;
        for (int c = 0; c < 3; ++c) {
            int& n = vertex_slot[t[c]];
            if (n < 0) {
                n = static_cast<int>(out.vertices.size());
                out.vertices.push_back(mesh.vertices[t[c]]);
            }
            renumbered[c] = n;
        }
        out.triangles.push_back(renumbered);
        if (flags) out.face_observed.push_back(mesh.face_observed[i]);
    }
    for (const std::uint32_t i : indices) {
        for (int c = 0; c < 3; ++c) vertex_slot[mesh.triangles[i][c]] = -1;
    }
    return out;
}

TriangleMesh crop_mesh(const TriangleMesh& mesh, const VoxelRegion& region) {
    // The region is in the mesh's frame.
    std::vector<std::uint32_t> inside;
    for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
        if (region.contains(triangle_centroid(mesh, mesh.triangles[i]))) {
            inside.push_back(static_cast<std::uint32_t>(i));
        }
    }
    std::vector<int> vertex_slot(mesh.vertices.size(), -1);
    return extract_triangles(mesh, inside, vertex_slot);
}

TriangleMesh restrict_observed(const TriangleMesh& reference, const VoxelRegion& region) {
    TriangleMesh out = reference;
    if (out.face_observed.size() != out.triangles.size()) {
        out.face_observed.assign(out.triangles.size(), 1);
    }
    for (std::size_t i = 0; i < out.triangles.size(); ++i) {
        if (out.face_observed[i] && !region.contains(triangle_centroid(out, out.triangles[i]))) {
            out.face_observed[i] = 0;
        }
    }
    return out;
}

}  // namespace shine
