// Where a trajectory comes back to a place, its scans there can be registered to each other
// directly: the relative pose the two scans agree on needs no chain of registrations in between.
// A trajectory that drifted between the visits disagrees with that direct registration by its
// drift, so the disagreement scores a trajectory without any ground truth -- and scores a
// reference trajectory (a LiDAR-inertial estimate, say) the same way as an estimate. This is the
// measurement behind a loop closure's constraint (the pose-graph literature's "loop closure
// edge"), used here only to measure.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <vector>

namespace shine {

/// Which scan pairs count as a revisit and how they are registered.
struct RevisitConfig {
    /// The two scans are at least this many scans apart in the sequence (so that the chain of
    /// registrations between them is long enough to drift).
    std::size_t min_gap_scans = 10;
    /// Their sensor positions are at most this far apart, m (so that they see the same place).
    double max_distance_m = 5.0;
    double min_range_m = 1.5;   ///< closer points are not used (the carrier itself)
    double max_range_m = 40.0;  ///< farther points are not used (sparse, noisy)
    /// The registered scan keeps one point per voxel of this size; the reference scan one per
    /// voxel a third as large, so that every point finds a plane on the same surface.
    double voxel_size_m = 0.3;
    /// A registration counts when at least this share of the points lie within 0.1 m of a
    /// reference plane at its result (two scans of the same place that overlap).
    double min_inlier_ratio = 0.5;
};

/// A pair of scans (indices into the caller's list, `first` < `second`).
struct RevisitPair {
    std::size_t first = 0;
    std::size_t second = 0;
    double distance_m = 0.0;  ///< between their positions, by the trajectory that chose them
};

/// For each scan, its nearest later scan that is at least min_gap_scans later in the sequence and
/// at most max_distance_m away, by `T_world_sensor` (one pose per scan; `sequence_number[i]` is
/// scan i's place in the sequence, so that held-out scans still count in the gap). Pairs in
/// the order of their first scan. Throws DataError if the counts differ.
std::vector<RevisitPair> find_revisits(const std::vector<Eigen::Isometry3d>& T_world_sensor,
                                       const std::vector<std::size_t>& sequence_number,
                                       const RevisitConfig& config);

/// The direct registration of one pair.
struct RevisitRegistration {
    bool accepted = false;  ///< ICP converged and the inlier share reached min_inlier_ratio
    double inlier_ratio = 0.0;
    std::size_t points = 0;  ///< the registered scan's points
    /// The pose of the second scan's sensor in the first scan's sensor frame.
    Eigen::Isometry3d T_first_second = Eigen::Isometry3d::Identity();
};

/// Registers `second_sensor` onto `first_sensor` (both as measured, sensor frame) by point-to-plane
/// ICP, coarse (1.5 m matches) then fine (0.5 m), started from `T_first_second_initial`.
RevisitRegistration register_revisit(const std::vector<Eigen::Vector3f>& first_sensor,
                                     const std::vector<Eigen::Vector3f>& second_sensor,
                                     const Eigen::Isometry3d& T_first_second_initial,
                                     const RevisitConfig& config);

/// How far apart two relative poses are: |t| and the rotation angle of a^-1 b.
struct PoseDisagreement {
    double translation_m = 0.0;
    double rotation_deg = 0.0;
};
PoseDisagreement pose_disagreement(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b);

}  // namespace shine
