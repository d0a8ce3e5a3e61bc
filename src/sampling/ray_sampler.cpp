#include "shine/sampling/ray_sampler.hpp"

#include <algorithm>
#include <cmath>

namespace shine {

void sample_ray(const Eigen::Vector3f& origin_map, const Eigen::Vector3f& endpoint_map,
                const Eigen::Vector3f& normal, const SamplingConfig& config, Pcg32& rng,
                RaySample* out) {
    const Eigen::Vector3f ray = endpoint_map - origin_map;
    const float range_m = ray.norm();
    const Eigen::Vector3f direction =
        range_m > 0.0f ? Eigen::Vector3f(ray / range_m) : Eigen::Vector3f::UnitZ();
    const bool has_normal = normal.squaredNorm() > 0.5f;
    const float scale =
        has_normal ? std::max(config.min_incidence_cosine, std::abs(normal.dot(direction))) : 1.0f;
    const bool along_normal = has_normal && config.surface_samples_along_normal;
    int n = 0;
    for (int i = 0; i < config.surface_samples; ++i, ++n) {
        const float offset_m = rng.uniform(-config.surface_band_m, config.surface_band_m);
        if (along_normal) {
            out[n] = {endpoint_map - offset_m * normal, -offset_m, SampleKind::kSurface};
        } else {
            const float t = std::max(0.0f, range_m + offset_m);
            out[n] = {origin_map + t * direction, scale * (range_m - t), SampleKind::kSurface};
        }
    }
    const float free_begin = config.free_space_start_ratio * range_m;
    const float free_end = std::max(free_begin, range_m - config.surface_band_m);
    for (int i = 0; i < config.free_samples; ++i, ++n) {
        const float t = rng.uniform(free_begin, free_end);
        out[n] = {origin_map + t * direction, scale * (range_m - t), SampleKind::kFreeSpace};
    }
}

}  // namespace shine
