#include "shine/mapper/replay_rays.hpp"

#include <algorithm>

namespace shine {

void ReplayRays::clear() {
    rays_.clear();
    first_serial_ = 0;
    live_first_scan_ = 0;
}

void ReplayRays::sync(const std::deque<ScanInMap>& scans,
                      const std::deque<std::vector<Eigen::Vector3f>>& normals,
                      std::uint64_t first_serial, std::size_t replayed, std::size_t changed) {
    const std::size_t n = scans.size();
    replayed = std::min(replayed, n);
    changed = std::min(changed, replayed);
    const std::uint64_t wanted_first = first_serial + (n - replayed);  // serials of the set
    const std::uint64_t wanted_end = first_serial + n;
    const std::uint64_t held_end = first_serial_ + rays_.num_scans();
    // The scans the set keeps: held, still wanted and not changed.
    const std::uint64_t keep_end = std::min(held_end, wanted_end - changed);
    if (rays_.num_scans() == 0 || keep_end < wanted_first || keep_end < first_serial_) {
        rays_.clear();
        first_serial_ = wanted_first;
        live_first_scan_ = 0;
        ++rebuilds_;
    } else {
        rays_.truncate(static_cast<std::uint32_t>(keep_end - first_serial_));
        live_first_scan_ = static_cast<std::uint32_t>(wanted_first - first_serial_);
    }
    for (std::uint64_t serial = first_serial_ + rays_.num_scans(); serial < wanted_end; ++serial) {
        const std::size_t w = static_cast<std::size_t>(serial - first_serial);
        const ScanInMap& scan = scans[w];
        // Normals estimated for other points than the scan now holds (a scan from before a
        // resume without replay) are not used.
        const bool with_normals = w < normals.size() && normals[w].size() == scan.points_map.size();
        static const std::vector<Eigen::Vector3f> kNone;
        const bool with_origins = scan.point_origins_map.size() == scan.points_map.size();
        rays_.add_scan_with_normals(scan.origin_map, scan.points_map,
                                    with_normals ? normals[w] : kNone,
                                    with_origins ? scan.point_origins_map : kNone);
    }
    // Cut the dead prefix away once it is more than a quarter of the live rays.
    const std::size_t dead = begin_ray();
    if (dead > 0 && 4 * dead > rays_.num_rays() - dead) {
        rays_.erase_front(live_first_scan_);
        first_serial_ += live_first_scan_;
        live_first_scan_ = 0;
    }
}

}  // namespace shine
