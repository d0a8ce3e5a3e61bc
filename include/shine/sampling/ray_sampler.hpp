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
    /// N_s and N_f per ray. Two surface samples and one free-space sample per ray spread a batch
    /// over more rays than the paper's larger counts, and score higher for the same work on the
    /// street (docs/performance.md); most free-space samples near the sensor fall outside the
    /// sparse map and are dropped anyway.
    int surface_samples = 2;
    int free_samples = 1;
    float surface_band_m = 0.3f;          ///< half-width of the surface band
    float free_space_start_ratio = 0.3f;  ///< free samples start at this fraction of the range
    /// With a normal: surface samples along the normal instead of the ray (else only the
    /// free-space labels are corrected for the incidence angle).
    bool surface_samples_along_normal = true;
    float min_incidence_cosine = 0.05f;  ///< labels shrink at most 1 / this for oblique rays
    /// Rays grouped by voxel (preprocess.voxel_points: all; ray_set.hpp): the share of a step's
    /// rays drawn uniformly over every point, the rest drawn as a uniform voxel and then one of
    /// its points. 0 spreads the samples over space as thinning does; 1 follows the points'
    /// density, which is highest near the sensor. No effect on ungrouped rays.
    float every_point_share = 0.7f;

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
///
/// `normal` is the unit surface normal at the endpoint oriented towards the sensor, or zero if
/// unknown (surface_normals.hpp). With a normal, labels become distances to the tangent plane:
/// surface samples lie at endpoint + d * normal with label d (or along the ray with the
/// projective label times |cos(incidence)|), and free-space labels are scaled by
/// |cos(incidence)|, clamped below at min_incidence_cosine.
void sample_ray(const Eigen::Vector3f& origin_map, const Eigen::Vector3f& endpoint_map,
                const Eigen::Vector3f& normal, const SamplingConfig& config, Pcg32& rng,
                RaySample* out);

}  // namespace shine
