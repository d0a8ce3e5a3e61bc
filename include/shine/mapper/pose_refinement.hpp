// Poses refined with the map (batch mode): the given poses of real data are imperfect (an ICP
// odometry drifts; a LiDAR-inertial one is off by centimetres), and a map trained at wrong poses
// blurs every surface the scans disagree on. Alternating with training, each scan is registered
// to the map of all scans (register_to_sdf on the NeuralSdf: the points' SDF values driven to
// zero) and its rays are moved rigidly to the registered pose; training then goes on with the
// moved rays, sharpening the map, which the next round registers against again.
//
// Why alternation and not a joint gradient on the poses: the registration is a Gauss-Newton
// solve on thousands of points per scan, converged in a few iterations, where a pose updated by
// Adam alongside the features would need a learning rate of its own per dataset; a round costs
// about as much as a few training steps (docs/field.md has the measurements).
//
// Gauge: registering every scan to a map made from all of them leaves the frame free to creep.
// After each round the new poses are aligned (SE(3), gauge_alignment(): least squares over each
// scan's position and, apart, its orientation, a radian weighing as gauge_lever_m metres) to the
// poses the round started from: the corrections do not move the map as a whole, which is the
// weighted prior towards the given poses that keeps the map in the data's frame (every scan
// weighted equally).
//
// A registration that fails (degenerate, no descent) or asks for a correction beyond
// max_correction_m / max_correction_deg keeps the scan where it was; one that runs out of
// iterations having cut the cost by min_unfinished_cost_cut moves it as far as it went.
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <vector>

#include "shine/model/neural_sdf.hpp"
#include "shine/sampling/ray_set.hpp"

namespace shine {

/// Settings of pose refinement (YAML section `refine`).
struct PoseRefinementRound;

/// How refinement changed the relative pose of consecutive scans (given T_a^-1 T_b against
/// refined T_a^-1 T_b, scan a then scan b): medians over the pairs.
struct RelativePoseChange {
    double median_translation_m = 0.0;
    double median_rotation_deg = 0.0;
};

/// RelativePoseChange of `refined` against `given` (one pose each per scan, in scan order; the
/// world frames may differ). Fewer than two scans: zeros. Throws DataError on a count mismatch.
RelativePoseChange relative_pose_change(const std::vector<Eigen::Isometry3d>& given,
                                        const std::vector<Eigen::Isometry3d>& refined);

struct PoseRefinementConfig {
    /// Rounds of registration during batch training, evenly spread between first_fraction and
    /// last_fraction of the steps; 0 turns refinement off.
    int rounds = 4;
    double first_fraction = 0.1;
    double last_fraction = 0.6;
    /// Registration points: at most one per voxel of this size (sensor frame). The lengths here
    /// are the outdoor ones at 0.2 m leaves; for other leaves the mapper scales them with the
    /// leaf (at_leaf()).
    double voxel_size_m = 0.3;
    double min_range_m = 1.5;   ///< closer points do not register
    double max_range_m = 60.0;  ///< farther points do not register
    /// Geman-McClure scale of the SDF residuals, coarse to fine: the first round's scale is
    /// coarse_kernel_scale_m (poses off by decimetres pull on a blurred map), the last's
    /// kernel_scale_m, the rounds between on a geometric scale.
    double coarse_kernel_scale_m = 0.2;
    double kernel_scale_m = 0.05;
    int max_iterations = 15;  ///< Levenberg-Marquardt iterations per scan and round
    /// At most this many registration points per scan and round, every k-th of the voxel
    /// selection (0: all of them). Measured with the warm start on the real drive and walk
    /// (docs/field.md): 3000 points score as the whole selection (10-15 k points on the drive)
    /// within 0.1 points of held-out rays within 10 cm at a third less CPU time for the run;
    /// 1500 lose 0.7 points on the drive.
    int max_points = 3000;
    /// The gauge's lever: in the alignment a radian of a scan's orientation weighs as this many
    /// metres of its position, so a given pose's rotation counts against its position as about
    /// 0.3 deg against 5 cm. At 1 m the roll about a straight drive was left to the positions'
    /// noise: on six simulated streets with 5 cm / 0.3 deg of noise per scan the refined frame
    /// landed 0.10-0.81 deg from the true one (F-score up to 19.6 points lower than at true
    /// poses); at 10 m the given poses' own frame error, 0.03-0.09 deg (docs/field.md). Until
    /// 2026-12-01 the orientation entered as points this far along the scan's axes, fitted with
    /// the positions by Umeyama, which let each scan's rotation noise move the translation and
    /// its position noise the rotation; fitted apart, ten noisy streets of ten came within 1
    /// point of F-score of their true-pose maps instead of eight.
    double gauge_lever_m = 10.0;
    /// A registration that runs out of max_iterations still moves its scan when it cut the
    /// cost by at least this share (refine_scan_poses: on noisy simulated streets such solves
    /// cut it by 42-95 %; at true poses among moving cars on a coarse map they crept by 4-7 %).
    double min_unfinished_cost_cut = 0.25;
    double max_correction_m = 1.0;    ///< larger corrections are rejected
    double max_correction_deg = 5.0;  ///< larger corrections are rejected
    /// The map at the refined poses starts from the first phase's map and trains the steps after
    /// the last round's (map_sequence), where that map's surfaces were sharp: where the poses it
    /// trained at (the given ones before the first round, each round's before the next) differ
    /// from the refined ones in the relative pose of consecutive scans by at most
    /// warm_start_max_relative_m and warm_start_max_relative_deg (the medians over the pairs,
    /// relative_pose_change(), the largest over those stretches:
    /// BatchMapper::refinement_relative_change()). Poses off by a smooth drift (real odometry)
    /// leave the first map sharp but bent, and the steps after the warm start straighten it;
    /// poses off by independent noise per scan leave it blurred, and the blur stays. Otherwise,
    /// or with false, it trains every step from scratch. Measured (docs/field.md): 9-13 mm and
    /// 0.05-0.07 deg on the real drive and walk, where the warm start scored as the cold one or
    /// better; 54 / 109 mm and 0.36 / 0.72 deg on streets with 2.5 cm / 0.15 deg and 5 cm /
    /// 0.3 deg of pose noise, where it lost 2.3 / 3.4 points of F-score. The bounds sit between
    /// the two kinds (the length scaled with the leaf).
    bool warm_start = true;
    double warm_start_max_relative_m = 0.025;
    double warm_start_max_relative_deg = 0.15;
    /// Incremental mode: its consolidation refines the kept scans' poses too, in place
    /// (IncrementalMapper::consolidate), with `rounds` rounds spread over its steps as above.
    /// Measured at given poses (docs/field.md): held-out rays within 10 cm 70.93 -> 74.50 % on
    /// the real drive, 88.50 -> 90.26 % on the real walk, the street at true poses level (F
    /// 96.42 %), the street with 5 cm / 0.3 deg pose noise 58.9 -> 81.9 %. With estimated poses
    /// (odometry), since the gauge's 10 m lever: drive / walk 58.45 -> 58.40 % / 73.29 -> 73.57 %
    /// at the data's poses, 74.49 -> 74.93 % / 90.60 -> 90.70 % next to the estimate, the street
    /// level (F 96.33 -> 96.29 %); with the 1 m lever it had lost 0.4-0.7 points at the data's
    /// poses, and was off unless set.
    bool in_consolidation = true;

    /// These settings for a map of `leaf_size_m` leaves whose scans keep ranges in [min_range_m,
    /// max_range_m]: the voxel, kernel and largest correction scaled by leaf / 0.2 m.
    PoseRefinementConfig at_leaf(double leaf_size_m, double min_range_m, double max_range_m) const;

    /// The training step at which round r (0-based) runs, of `iterations` steps.
    int round_step(int round, int iterations) const;
    /// The kernel scale of round r (0-based).
    double round_kernel_scale_m(int round) const;
    /// Whether the map at the refined poses may start from the first phase's map, whose training
    /// poses differ from the refined ones by `change` (warm_start and its bounds).
    bool warm_start_fits(const RelativePoseChange& change) const;
};

/// What one round did.
struct PoseRefinementRound {
    int step = 0;              ///< the training step before which it ran
    std::size_t accepted = 0;  ///< scans moved
    /// Of the accepted: solves that ran out of iterations having cut the cost by
    /// min_unfinished_cost_cut (the scan moved as far as they went).
    std::size_t unfinished = 0;
    std::size_t rejected = 0;  ///< scans kept (failed, degenerate or too large a correction)
    double median_translation_m = 0.0;  ///< of the accepted corrections
    double median_rotation_deg = 0.0;
    double max_translation_m = 0.0;
    double gauge_translation_m = 0.0;  ///< how far the gauge alignment moved the mean position
    double seconds = 0.0;
};

/// The rigid transform G that best moves `poses` onto `reference` (one each per scan, scan
/// order): least squares over each scan's position (metres) and its orientation (the rotation
/// vector between them, times `lever_m`), solved by Gauss-Newton about the positions' centroid.
/// Fewer than three scans: identity. Throws DataError on a count mismatch.
Eigen::Isometry3d gauge_alignment(const std::vector<Eigen::Isometry3d>& poses,
                                  const std::vector<Eigen::Isometry3d>& reference, double lever_m);

/// Round `round_index`: every scan of `rays` registered to `sdf` from its pose `T_map_sensor[s]`
/// (map frame: the world less sdf.origin_world_m), the registered poses gauge-aligned to the
/// given ones (file comment). Returns the new poses, one per scan; `round` (optional) gets the
/// figures. Throws DataError if the pose count differs from the scan count.
std::vector<Eigen::Isometry3d> refine_scan_poses(const NeuralSdf& sdf, const RaySet& rays,
                                                 const std::vector<Eigen::Isometry3d>& T_map_sensor,
                                                 const PoseRefinementConfig& config,
                                                 int round_index,
                                                 PoseRefinementRound* round = nullptr);

/// Moves every scan of `rays` from `T_map_sensor_old[s]` to `T_map_sensor_new[s]`.
void move_scans(RaySet& rays, const std::vector<Eigen::Isometry3d>& T_map_sensor_old,
                const std::vector<Eigen::Isometry3d>& T_map_sensor_new);

/// Poses of held-out scans from the corrections of the mapped scans around them, never from their
/// own points: with the body-frame correction D(s) = T_given(s)^-1 T_refined(s) of each mapped
/// scan, a held-out scan h between mapped scans a < h < b gets T_given(h) D(h) with D(h)
/// interpolated between D(a) and D(b) by frame number (translation linearly, rotation by slerp);
/// one before the first or after the last mapped scan takes that scan's correction.
/// `is_mapped[i]` says which of `given` are mapped; `refined_mapped` holds the refined poses of
/// the mapped ones in order; `frame_number[i]` orders the scans in time. Returns a pose for every
/// scan (the mapped ones refined). Throws DataError for mismatched counts or no mapped scan.
std::vector<Eigen::Isometry3d> interpolate_corrections(
    const std::vector<Eigen::Isometry3d>& given, const std::vector<bool>& is_mapped,
    const std::vector<Eigen::Isometry3d>& refined_mapped, const std::vector<double>& frame_number);

}  // namespace shine
