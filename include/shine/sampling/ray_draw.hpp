// Drawing a training ray from a range of a RaySet's rays. Ungrouped rays are drawn uniformly.
// Rays grouped by voxel (ray_set.hpp) are drawn from a mixture: with probability
// every_point_share uniformly over the rays, which follows the points' density (highest near the
// sensor), otherwise as a uniform voxel and then one of its rays, which spreads the draws over
// space as thinning to one point per voxel does while still using every point.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>

#include "shine/core/random.hpp"
#include "shine/sampling/ray_set.hpp"

namespace shine {

class RayDrawer {
  public:
    /// Draws from rays [ray_begin, ray_end); with voxel groups both ends must be scan boundaries
    /// (or group boundaries).
    RayDrawer(const RaySet& rays, std::size_t ray_begin, std::size_t ray_end,
              float every_point_share)
        : rays_(rays),
          ray_begin_(ray_begin),
          ray_end_(ray_end),
          group_begin_(rays.group_at_or_after(ray_begin)),
          group_end_(rays.group_at_or_after(ray_end)),
          point_threshold_(rays.grouped() ? static_cast<std::uint64_t>(std::ldexp(
                                                static_cast<double>(every_point_share), 24))
                                          : 0) {}

    bool empty() const { return group_end_ <= group_begin_; }

    /// One ray index; the range must not be empty. Ungrouped rays take one draw of `rng`, exactly
    /// a plain uniform draw of the range.
    std::size_t draw(Pcg32& rng) const {
        if (point_threshold_ > 0 && rng.below64(std::uint64_t{1} << 24) < point_threshold_) {
            return ray_begin_ + rng.below64(ray_end_ - ray_begin_);
        }
        const std::size_t group = group_begin_ + rng.below64(group_end_ - group_begin_);
        const std::size_t first = rays_.first_ray_of_group(group);
        const std::size_t size = rays_.first_ray_of_group(group + 1) - first;
        return size > 1 ? first + rng.below64(size) : first;
    }

  private:
    const RaySet& rays_;
    std::size_t ray_begin_, ray_end_;
    std::size_t group_begin_, group_end_;
    std::uint64_t point_threshold_;  ///< every_point_share in units of 2^-24 (0: never)
};

}  // namespace shine
