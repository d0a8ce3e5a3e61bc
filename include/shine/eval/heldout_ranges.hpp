// The ground-truth-free yardstick: score a map on scans it never saw.
//
// Real recordings come without a reference surface, and a map scored on the scans it was trained
// on rewards memorising their noise. Held-out scans are an honest reference: each of their rays
// is cast from the held-out sensor pose into the map's surface (a triangle mesh, so the neural
// map and the TSDF baseline are judged by the same caster), and the range where the ray first
// hits the surface is compared with the range the LiDAR measured along it:
//
//   - hit ratio: rays that hit the surface no farther than measured range + overshoot_m;
//   - median and mean |predicted - measured| range over the hits;
//   - within ratio: rays whose error is at most threshold_m, over all scored rays (a miss counts
//     as a failure, so a map cannot score well by covering little).
//
// Rays are scored from the raw scan (no downsampling) with the mapping's range limits; overall
// figures pool every ray of every held-out scan, and each scan also gets its own.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "shine/geometry/ray_caster.hpp"
#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/scan_sequence.hpp"

namespace shine {

struct HeldoutConfig {
    double threshold_m = 0.10;  ///< a ray is good when its range error is at most this
    double min_range_m = 1.5;   ///< measured ranges outside [min, max] are not scored
    double max_range_m = 60.0;
    /// A ray that meets no surface up to its measured range plus this is a miss. A hit beyond the
    /// measured point (the surface lies behind where the LiDAR saw it) is still a hit, with its
    /// error.
    double overshoot_m = 1.0;
};

/// Counts and range errors of a set of rays.
struct RangeErrorStats {
    std::size_t rays = 0;             ///< rays scored (measured range within the limits)
    std::size_t hits = 0;             ///< rays that met the surface
    std::size_t within = 0;           ///< hits with |error| <= threshold
    double median_abs_error_m = 0.0;  ///< over the hits; 0 without hits
    double mean_abs_error_m = 0.0;    ///< over the hits; 0 without hits

    double hit_ratio() const { return rays ? double(hits) / double(rays) : 0.0; }
    /// Share of all scored rays within the threshold (misses are failures).
    double within_ratio() const { return rays ? double(within) / double(rays) : 0.0; }
};

/// One held-out scan's result.
struct HeldoutScan {
    std::size_t frame = 0;  ///< index in the sequence as opened
    std::filesystem::path source;
    RangeErrorStats stats;
};

struct HeldoutReport {
    HeldoutConfig config;
    std::vector<HeldoutScan> scans;
    RangeErrorStats total;  ///< every ray of every scan pooled
};

/// |predicted - measured| range of each scored ray of one scan (hits only), and the counts.
/// `surface` holds the map's mesh in the frame whose world position is `origin_world_m`
/// (TriangleMesh::origin_world_m); `points_sensor` and `T_world_sensor` are the held-out scan.
/// Non-finite points are not scored. Parallel; the result does not depend on the thread count.
RangeErrorStats score_scan_ranges(const RayCaster& surface, const Eigen::Vector3d& origin_world_m,
                                  const std::vector<Eigen::Vector3f>& points_sensor,
                                  const Eigen::Isometry3d& T_world_sensor,
                                  const HeldoutConfig& config,
                                  std::vector<float>* abs_errors_m = nullptr);

/// What is done to a held-out scan after loading and before scoring (deskewing it with the
/// poses around it); `frame` is its index in the sequence.
using ScanPreparation = std::function<void(std::size_t frame, Scan& scan)>;

/// Scores the scans `frames` of `sequence` against `mesh`, each passed through `prepare` first
/// when given. Throws ConfigError for a frame outside the sequence, an empty frame list or a mesh
/// without triangles (naming it), and the readers' errors for a broken scan.
HeldoutReport evaluate_heldout(const TriangleMesh& mesh, const ScanSequence& sequence,
                               const std::vector<std::size_t>& frames,
                               const HeldoutConfig& config = {},
                               const ScanPreparation& prepare = {});

/// The frames `shine map --holdout-every N` holds out of a sequence of `num_scans`: every N-th,
/// starting with the N-th (index N-1), so the first scan is always mapped. N >= 2.
std::vector<std::size_t> holdout_frames(std::size_t num_scans, int every);

/// Parses a frame list: comma-separated indices and ranges "first:last[:step]" (inclusive),
/// e.g. "2,5,8" or "2:52:3". Throws ConfigError naming the bad item, or an index >= num_scans.
std::vector<std::size_t> parse_frame_list(const std::string& text, std::size_t num_scans);

/// A block for terminals: the pooled figures, then one line per scan (cm and %).
std::string format_heldout(const HeldoutReport& report);

/// One JSON object: config, total and per-scan figures (metres, ratios in [0, 1]); `indent` < 0
/// gives a single line.
std::string heldout_to_json(const HeldoutReport& report, int indent = -1);

}  // namespace shine
