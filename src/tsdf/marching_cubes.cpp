#include "shine/tsdf/marching_cubes.hpp"

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>

namespace shine {
namespace marching_cubes_internal {
namespace {

struct Face {
    int corners[4];  ///< in cyclic order: consecutive corners share a cube edge
    int normal[3];   ///< outward normal
};

constexpr Face kFaces[6] = {
    {{0, 3, 7, 4}, {-1, 0, 0}}, {{1, 2, 6, 5}, {1, 0, 0}},  {{0, 1, 5, 4}, {0, -1, 0}},
    {{3, 2, 6, 7}, {0, 1, 0}},  {{0, 1, 2, 3}, {0, 0, -1}}, {{4, 5, 6, 7}, {0, 0, 1}},
};

Eigen::Vector3d corner_position(int c) {
    return {double(kCubeCorner[c][0]), double(kCubeCorner[c][1]), double(kCubeCorner[c][2])};
}

int edge_between(int a, int b) {
    for (int e = 0; e < 12; ++e) {
        if ((kCubeEdge[e][0] == a && kCubeEdge[e][1] == b) ||
            (kCubeEdge[e][0] == b && kCubeEdge[e][1] == a)) {
            return e;
        }
    }
    throw std::logic_error("marching cubes: corners " + std::to_string(a) + " and " +
                           std::to_string(b) + " share no edge");
}

Eigen::Vector3d edge_midpoint(int e) {
    return 0.5 * (corner_position(kCubeEdge[e][0]) + corner_position(kCubeEdge[e][1]));
}

/// Appends the oriented segment between crossed edges e0 and e1 of a face: oriented so that
/// `to_positive` (a vector in the face plane pointing from the negative to the positive side)
/// equals normal x direction, i.e. the positive side is on the left seen from outside.
void add_segment(int e0, int e1, const Eigen::Vector3d& normal, const Eigen::Vector3d& to_positive,
                 int next[12]) {
    const Eigen::Vector3d direction = to_positive.cross(normal);
    if ((edge_midpoint(e1) - edge_midpoint(e0)).dot(direction) < 0.0) std::swap(e0, e1);
    if (next[e0] != -1) throw std::logic_error("marching cubes: edge leaves twice");
    next[e0] = e1;
}

/// How well triangle (e0, e1, e2), with vertices at the edge midpoints, faces the positive side:
/// its normal dotted with the negative-to-positive direction of its three edges, divided by the
/// normal's length (0 for a triangle lying in a cube face).
double facing(int mask, int e0, int e1, int e2) {
    const Eigen::Vector3d n =
        (edge_midpoint(e1) - edge_midpoint(e0)).cross(edge_midpoint(e2) - edge_midpoint(e0));
    if (n.norm() < 1e-9) return -std::numeric_limits<double>::infinity();  // degenerate
    double score = 0.0;
    for (int e : {e0, e1, e2}) {
        const int a = kCubeEdge[e][0], b = kCubeEdge[e][1];
        const Eigen::Vector3d to_positive = (mask >> a) & 1
                                                ? corner_position(b) - corner_position(a)
                                                : corner_position(a) - corner_position(b);
        score += n.dot(to_positive);
    }
    return score / n.norm();
}

MarchingCubesCase build_case(int mask) {
    MarchingCubesCase result;
    auto negative = [mask](int corner) { return (mask >> corner) & 1; };
    int next[12];
    for (int& n : next) n = -1;
    for (const Face& face : kFaces) {
        const Eigen::Vector3d normal(face.normal[0], face.normal[1], face.normal[2]);
        int crossed[4];
        int num_crossed = 0;
        for (int k = 0; k < 4; ++k) {
            const int a = face.corners[k], b = face.corners[(k + 1) % 4];
            if (negative(a) != negative(b)) crossed[num_crossed++] = edge_between(a, b);
        }
        if (num_crossed == 2) {
            Eigen::Vector3d positive_sum = Eigen::Vector3d::Zero();
            Eigen::Vector3d negative_sum = Eigen::Vector3d::Zero();
            int num_negative = 0;
            for (int c : face.corners) {
                if (negative(c)) {
                    negative_sum += corner_position(c);
                    ++num_negative;
                } else {
                    positive_sum += corner_position(c);
                }
            }
            const Eigen::Vector3d to_positive =
                positive_sum / (4 - num_negative) - negative_sum / num_negative;
            add_segment(crossed[0], crossed[1], normal, to_positive, next);
        } else if (num_crossed == 4) {
            // Ambiguous face: cut off each negative corner with its own segment.
            Eigen::Vector3d centre = Eigen::Vector3d::Zero();
            for (int c : face.corners) centre += 0.25 * corner_position(c);
            for (int k = 0; k < 4; ++k) {
                const int c = face.corners[k];
                if (!negative(c)) continue;
                const int before = face.corners[(k + 3) % 4], after = face.corners[(k + 1) % 4];
                add_segment(edge_between(before, c), edge_between(c, after), normal,
                            centre - corner_position(c), next);
            }
        }
    }
    // Every crossed edge lies on two faces: it must start exactly one segment and end one.
    int incoming[12] = {0};
    for (int e = 0; e < 12; ++e) {
        if (next[e] != -1) {
            result.edge_mask |= static_cast<std::uint16_t>(1u << e);
            ++incoming[next[e]];
        }
    }
    for (int e = 0; e < 12; ++e) {
        if (incoming[e] != ((result.edge_mask >> e) & 1)) {
            throw std::logic_error("marching cubes: open loop in case " + std::to_string(mask));
        }
    }
    bool used[12] = {false};
    for (int start = 0; start < 12; ++start) {
        if (next[start] == -1 || used[start]) continue;
        std::vector<int> loop;
        for (int e = start; !used[e]; e = next[e]) {
            used[e] = true;
            loop.push_back(e);
        }
        // Fan from the apex whose worst triangle faces the positive side best: a loop that is
        // not planar (up to 6 edges) would otherwise get triangles lying flat in a cube face.
        const std::size_t n = loop.size();
        std::size_t best_apex = 0;
        double best_score = -std::numeric_limits<double>::infinity();
        for (std::size_t apex = 0; apex < n; ++apex) {
            double worst = std::numeric_limits<double>::infinity();
            for (std::size_t i = 1; i + 1 < n; ++i) {
                worst = std::min(worst, facing(mask, loop[apex], loop[(apex + i) % n],
                                               loop[(apex + i + 1) % n]));
            }
            if (worst > best_score) {
                best_score = worst;
                best_apex = apex;
            }
        }
        for (std::size_t i = 1; i + 1 < n; ++i) {
            result.triangles.push_back({static_cast<std::uint8_t>(loop[best_apex]),
                                        static_cast<std::uint8_t>(loop[(best_apex + i) % n]),
                                        static_cast<std::uint8_t>(loop[(best_apex + i + 1) % n])});
        }
    }
    return result;
}

}  // namespace
}  // namespace marching_cubes_internal

const std::array<MarchingCubesCase, 256>& marching_cubes_table() {
    static const std::array<MarchingCubesCase, 256> table = [] {
        std::array<MarchingCubesCase, 256> t;
        for (int mask = 0; mask < 256; ++mask) t[mask] = marching_cubes_internal::build_case(mask);
        return t;
    }();
    return table;
}

}  // namespace shine
