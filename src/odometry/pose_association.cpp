// Nearest-timestamp pairing of two trajectories.
#include "shine/odometry/pose_association.hpp"

#include <algorithm>
#include <cmath>

#include "shine/core/error.hpp"
#include "shine/io/pose_interpolation.hpp"

namespace shine {

PosePairs associate_by_time(const std::vector<StampedPose>& estimate,
                            const std::vector<StampedPose>& reference, double max_time_difference_s,
                            const std::string& estimate_source,
                            const std::string& reference_source) {
    if (!(max_time_difference_s >= 0.0)) {
        throw ConfigError("the largest time difference of a pose pair must be >= 0 s (got " +
                          std::to_string(max_time_difference_s) + ")");
    }
    check_pose_times(estimate, estimate_source);
    check_pose_times(reference, reference_source);
    PosePairs pairs;
    std::size_t next_free = 0;  // reference poses before this one are taken or passed
    for (std::size_t i = 0; i < estimate.size(); ++i) {
        const double t = estimate[i].timestamp_s;
        const auto it = std::lower_bound(
            reference.begin(), reference.end(), t,
            [](const StampedPose& p, double time) { return p.timestamp_s < time; });
        std::size_t best = std::size_t(it - reference.begin());
        if (best == reference.size() ||
            (best > 0 && t - reference[best - 1].timestamp_s < reference[best].timestamp_s - t)) {
            if (best == 0) continue;
            --best;
        }
        if (best < next_free) continue;
        if (std::abs(reference[best].timestamp_s - t) > max_time_difference_s) continue;
        pairs.emplace_back(i, best);
        next_free = best + 1;
    }
    return pairs;
}

}  // namespace shine
