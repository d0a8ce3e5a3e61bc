// The rays incremental mode trains on, kept from scan to scan.
//
// Each scan trains on the last replay_frames scans of the window (incremental_mapper.hpp): up to
// 100 scans, 1.6 M rays on the street. Assembling that set afresh for every scan copied ~45 MB
// into newly faulted pages, ~6 ms of a 90 ms frame. Between two scans the set changes only at its
// ends: the new scan joins, the oldest may leave, and the dynamic-point filter thins the last few
// scans (those the new scan saw through). So the set is kept: the changed scans at the end are
// taken anew, the scans that left stay as a dead prefix (training draws from the live range
// only), and the prefix is cut away in one move once it exceeds a quarter of the live rays.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <vector>

#include "shine/mapper/scan_in_map.hpp"
#include "shine/sampling/ray_set.hpp"

namespace shine {

class ReplayRays {
  public:
    /// Brings the set to the last `replayed` scans of the window `scans` (normals[w] the
    /// normals of scans[w], or empty: zero normals), where scans[w] is the scan numbered
    /// first_serial + w since the mapper began. The last `changed` scans of the window are taken
    /// anew even if the set has them; everything else the set holds is kept as it is.
    void sync(const std::deque<ScanInMap>& scans,
              const std::deque<std::vector<Eigen::Vector3f>>& normals, std::uint64_t first_serial,
              std::size_t replayed, std::size_t changed);
    /// Forgets every scan (a restored state: the next sync() assembles the set afresh).
    void clear();

    const RaySet& rays() const { return rays_; }
    /// The live rays: [begin_ray(), rays().num_rays()).
    std::size_t begin_ray() const { return rays_.first_ray(live_first_scan_); }
    /// The first ray of the last scan.
    std::size_t last_scan_begin_ray() const {
        return rays_.num_scans() == 0
                   ? rays_.num_rays()
                   : rays_.first_ray(static_cast<std::uint32_t>(rays_.num_scans() - 1));
    }
    std::size_t live_scans() const { return rays_.num_scans() - live_first_scan_; }
    /// Times the set was assembled from nothing (the first scan, a restored state).
    std::size_t rebuilds() const { return rebuilds_; }

  private:
    RaySet rays_;
    std::uint64_t first_serial_ = 0;     ///< the serial number of rays_'s scan 0
    std::uint32_t live_first_scan_ = 0;  ///< rays_'s scans before it have left the window
    std::size_t rebuilds_ = 0;
};

}  // namespace shine
