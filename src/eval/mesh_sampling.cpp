#include "shine/eval/mesh_sampling.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <cmath>
#include <string>

#include "shine/core/error.hpp"

namespace shine {
namespace mesh_sampling_internal {

/// SplitMix64: a tiny, well-mixed generator; one instance per triangle keeps sampling independent
/// of the thread schedule.
class SplitMix64 {
  public:
    explicit SplitMix64(std::uint64_t state) : state_(state) {}

    std::uint64_t next() {
        std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
        return z ^ (z >> 31);
    }

    /// Uniform in [0, 1) with 53 random bits.
    double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

  private:
    std::uint64_t state_;
};

/// The generator of triangle `index`: the seed and index are mixed so that neighbouring
/// triangles and neighbouring seeds give unrelated streams.
SplitMix64 triangle_generator(std::uint64_t seed, std::size_t index) {
    SplitMix64 mix(seed ^ (0xD1B54A32D192ED03ULL * (static_cast<std::uint64_t>(index) + 1)));
    return SplitMix64(mix.next());
}

void validate_mesh(const TriangleMesh& mesh) {
    if (!mesh.face_observed.empty() && mesh.face_observed.size() != mesh.triangles.size()) {
        throw DataError("mesh has " + std::to_string(mesh.face_observed.size()) +
                        " face_observed flags for " + std::to_string(mesh.triangles.size()) +
                        " triangles; give one flag per triangle or none");
    }
    const auto vertex_count = static_cast<long long>(mesh.vertices.size());
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        for (int k = 0; k < 3; ++k) {
            const long long v = mesh.triangles[t][k];
            if (v < 0 || v >= vertex_count) {
                throw DataError("mesh triangle " + std::to_string(t) + " refers to vertex " +
                                std::to_string(v) + ", but the mesh has " +
                                std::to_string(vertex_count) + " vertices");
            }
        }
    }
}

bool is_selected(const TriangleMesh& mesh, std::size_t t, FaceSelection faces) {
    return faces == FaceSelection::kAll || mesh.face_observed.empty() || mesh.face_observed[t] != 0;
}

/// Corners of triangle `t` in double precision (samples are computed in double, stored in float).
struct Corners {
    Eigen::Vector3d a, ab, ac;
};

Corners corners(const TriangleMesh& mesh, std::size_t t) {
    const Eigen::Vector3i& tri = mesh.triangles[t];
    const Eigen::Vector3d a = mesh.vertices[tri[0]].cast<double>();
    return {a, mesh.vertices[tri[1]].cast<double>() - a, mesh.vertices[tri[2]].cast<double>() - a};
}

/// Area in m^2, 0 for degenerate or non-finite triangles.
double triangle_area_m2(const Corners& c) {
    const double area = 0.5 * c.ab.cross(c.ac).norm();
    return std::isfinite(area) && area > kDegenerateTriangleAreaM2 ? area : 0.0;
}

}  // namespace mesh_sampling_internal

double mesh_surface_area_m2(const TriangleMesh& mesh, FaceSelection faces) {
    using namespace mesh_sampling_internal;
    validate_mesh(mesh);
    double area_m2 = 0.0;  // serial double sum: exact enough and reproducible
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
        if (is_selected(mesh, t, faces)) area_m2 += triangle_area_m2(corners(mesh, t));
    }
    return area_m2;
}

std::vector<Eigen::Vector3f> sample_mesh_surface(const TriangleMesh& mesh, double density_per_m2,
                                                 std::uint64_t seed, FaceSelection faces) {
    using namespace mesh_sampling_internal;
    if (!(density_per_m2 > 0.0) || !std::isfinite(density_per_m2)) {
        throw DataError("sampling density " + std::to_string(density_per_m2) +
                        " points/m^2 is invalid; it must be positive and finite");
    }
    validate_mesh(mesh);
    const std::size_t n_triangles = mesh.triangles.size();

    // Pass 1: per-triangle counts by stochastic rounding of area * density; the first draw of each
    // triangle's generator decides the rounding, the following draws place its points.
    std::vector<std::size_t> offsets(n_triangles + 1, 0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n_triangles),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t t = range.begin(); t != range.end(); ++t) {
                              if (!is_selected(mesh, t, faces)) continue;
                              const double expected =
                                  triangle_area_m2(corners(mesh, t)) * density_per_m2;
                              if (expected <= 0.0) continue;
                              SplitMix64 rng = triangle_generator(seed, t);
                              const double whole = std::floor(expected);
                              offsets[t + 1] = static_cast<std::size_t>(whole) +
                                               (rng.uniform() < expected - whole ? 1 : 0);
                          }
                      });
    for (std::size_t t = 0; t < n_triangles; ++t) offsets[t + 1] += offsets[t];

    // Pass 2: uniform points in each triangle (reflecting (u, v) into the lower half of the unit
    // square maps it uniformly onto the triangle).
    std::vector<Eigen::Vector3f> points(offsets.back());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n_triangles),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t t = range.begin(); t != range.end(); ++t) {
                              if (offsets[t + 1] == offsets[t]) continue;
                              const Corners c = corners(mesh, t);
                              SplitMix64 rng = triangle_generator(seed, t);
                              rng.uniform();  // the rounding draw of pass 1
                              for (std::size_t i = offsets[t]; i < offsets[t + 1]; ++i) {
                                  double u = rng.uniform();
                                  double v = rng.uniform();
                                  if (u + v > 1.0) {
                                      u = 1.0 - u;
                                      v = 1.0 - v;
                                  }
                                  points[i] = (c.a + u * c.ab + v * c.ac).cast<float>();
                              }
                          }
                      });
    return points;
}

}  // namespace shine
