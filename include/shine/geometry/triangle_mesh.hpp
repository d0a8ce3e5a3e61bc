// A triangle mesh in world coordinates (metres).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

namespace shine {

/// Indexed triangle mesh. `face_observed` is optional (empty, or one flag per triangle): the
/// simulator marks the reference triangles that at least one LiDAR ray hit, and evaluation counts
/// completion only over those.
struct TriangleMesh {
    std::vector<Eigen::Vector3f> vertices;
    std::vector<Eigen::Vector3i> triangles;
    std::vector<std::uint8_t> face_observed;

    bool empty() const { return triangles.empty(); }
};

}  // namespace shine
