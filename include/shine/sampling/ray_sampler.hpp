// Training samples along LiDAR rays with projective signed-distance labels (paper Sec. III-B).
//
// For a ray from the sensor origin to a measured endpoint at range r, N_s samples fall uniformly in
// the surface band r +- surface_band_m and N_f samples uniformly in free space between
// free_space_start_ratio * r and the band's near edge. The label of a sample at distance t along
// the ray is the projective signed distance d = r - t: positive in free space, negative behind
// the surface.
#pragma once

#include <Eigen/Core>
#include <cstdint>

#include "shine/core/random.hpp"

namespace shine {

struct SamplingConfig {
    int surface_samples = 3;              ///< N_s per ray
    int free_samples = 3;                 ///< N_f per ray
    float surface_band_m = 0.3f;          ///< half-width of the surface band
    float free_space_start_ratio = 0.3f;  ///< free samples start at this fraction of the range

    int samples_per_ray() const { return surface_samples + free_samples; }
};

enum class SampleKind : std::uint8_t { kSurface = 0, kFreeSpace = 1 };

/// One training pair: a point in the map frame and its label.
struct RaySample {
    Eigen::Vector3f point_map;
    float sdf_label_m;
    SampleKind kind;
};

/// Writes config.samples_per_ray() samples of the ray origin -> endpoint into `out`
/// (surface samples first). A ray shorter than the band gets free samples clamped to the origin.
/// Labels are multiplied by `label_scale` (|cos(incidence)| turns them into tangent-plane
/// distances, see incidence.hpp).
void sample_ray(const Eigen::Vector3f& origin_map, const Eigen::Vector3f& endpoint_map,
                const SamplingConfig& config, Pcg32& rng, RaySample* out,
                float label_scale = 1.0f);

}  // namespace shine
