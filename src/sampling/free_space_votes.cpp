#include "shine/sampling/free_space_votes.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <limits>
#include <string>

#include "shine/core/error.hpp"

namespace shine {

void add_free_space_votes(const RangeImage& image, const Eigen::Isometry3f& T_sensor_map,
                          const Eigen::Vector3f* points_map, std::size_t count,
                          const DynamicPointConfig& config, FreeSpaceVotes* votes, bool far) {
    if (image.empty() || count == 0) return;
    constexpr std::uint16_t kMaxVotes = std::numeric_limits<std::uint16_t>::max();
    const float beam_m_per_m = config.beam_margin * image.bin_rad();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, count, 2048),
                      [&](const tbb::blocked_range<std::size_t>& range) {
                          for (std::size_t i = range.begin(); i != range.end(); ++i) {
                              const Eigen::Vector3f q = T_sensor_map * points_map[i];
                              const float d = q.norm();
                              if (!(d > 0.0f)) continue;
                              const RangeLookup seen = image.nearest_around(q, config.window_bins);
                              if (seen.returns == 0) continue;
                              const float margin = config.margin_m + beam_m_per_m * d;
                              FreeSpaceVotes& v = votes[i];
                              std::uint16_t& free = far ? v.far_free : v.free;
                              std::uint16_t& hit = far ? v.far_hit : v.hit;
                              if (seen.min_range_m > d + margin) {
                                  if (free < kMaxVotes) ++free;
                              } else if (seen.min_range_m >= d - margin) {
                                  if (hit < kMaxVotes) ++hit;
                              }
                          }
                      });
}

namespace {
bool free_enough(std::uint16_t free, std::uint16_t hit, int min_free_votes, float min_free_share) {
    if (free < min_free_votes || free == 0) return false;
    const float voted = static_cast<float>(free) + static_cast<float>(hit);
    return static_cast<float>(free) >= min_free_share * voted;
}
}  // namespace

bool is_dynamic(const FreeSpaceVotes& votes, const DynamicPointConfig& config) {
    if (free_enough(votes.free, votes.hit, config.min_free_votes, config.min_free_share)) {
        return true;
    }
    return votes.hit <= config.far_max_near_hits &&
           free_enough(votes.far_free, votes.far_hit, config.min_free_votes,
                       config.far_min_free_share);
}

void check_dynamic_point_config(const DynamicPointConfig& config) {
    const auto fail = [](const std::string& key, const std::string& what) {
        throw ConfigError("dynamic." + key + " " + what);
    };
    if (config.vote_frames < 1) fail("vote_frames", "must be at least 1");
    if (config.window_bins < 0) fail("window_bins", "must be >= 0");
    if (!(config.margin_m > 0.0f)) fail("margin_m", "must be positive");
    if (!(config.beam_margin >= 0.0f)) fail("beam_margin", "must be >= 0");
    if (config.min_free_votes < 1) fail("min_free_votes", "must be at least 1");
    if (!(config.min_free_share > 0.0f && config.min_free_share <= 1.0f)) {
        fail("min_free_share", "must be in (0, 1]");
    }
    if (config.far_vote_frames < 0) fail("far_vote_frames", "must be >= 0");
    if (config.far_max_near_hits < 0) fail("far_max_near_hits", "must be >= 0");
    if (!(config.far_min_free_share > 0.0f && config.far_min_free_share <= 1.0f)) {
        fail("far_min_free_share", "must be in (0, 1]");
    }
}

}  // namespace shine
