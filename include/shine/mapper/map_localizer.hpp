// Localisation in a saved map (`shine localize`): the pose of each scan in a neural map that is
// never changed, by registration of the scan to the map's SDF (sdf_registration.hpp through
// NeuralSdfField), without training.
//
// Per scan:
//   1. the registration points: range window, one point per voxel, at most max_points of them
//      for tracking and recovery_max_points for steps 4-5 (a deterministic stride:
//      registration_points.hpp);
//   2. tracking: registration to the SDF coarse to fine (kernel_scales_m) from the best of a few
//      starts around the constant-velocity prediction of the last two poses (the first scan:
//      the initial pose): the prediction if it scores at least prediction_good_score, else the
//      best of it and the last motion scaled (scans at uneven intervals, a stop, a start) and
//      turned about the vertical by a few degrees, each scored by the share of a few hundred
//      points near the surface; the SDF's basin is about 2 degrees and 0.25 m wide (measured on
//      the real walk), narrower than a hand-held sensor's turn between scans half a second apart;
//   3. the result counts as localised when the solver accepts it (converged, well conditioned)
//      AND at least min_inlier_ratio of the registration points lie within inlier_distance_m
//      of the map's surface there: a scan leaving the map, or pulled into a wrong minimum, has
//      few such points even when the solver converges;
//   4. when tracking fails (or its best start scores under track_min_start_score), a recovery
//      with a wider basin: point-to-plane ICP against the map's surface (its zero level set
//      baked at surface_voxel_m, mesh vertices with their normals, their nearest ones looked up
//      by voxel: VoxelNearestLookup), coarse to fine (icp_coarse_correspondence_m, then
//      icp_correspondence_m) from the prediction (the best start when tracking was skipped)
//      and, when ICP leaves fewer than icp_min_inlier_ratio of the points on a plane,
//      from the last pose turned to search_headings headings about the world's vertical axis
//      (nearest first, until one puts enough points on a plane); the best start is then
//      registered to the SDF as in step 2;
//   5. a scan that still fails takes the prediction (reported, not localised); after
//      global_search_after_failures such scans in a row (and for the first scan when no initial
//      pose is given) a global search runs: every place of `places` (the map's trajectory,
//      thinned to place_spacing_m) moved on a horizontal grid (search_radius_m,
//      search_spacing_m) and turned to each heading is scored by the share of a few hundred
//      points near the surface, and the best search_registrations candidates are registered by
//      ICP and then the SDF. Without the map's trajectory the search's centres are the
//      prediction and the last localised pose, within lost_search_radius_m.
// The SDF is metric only near surfaces (a narrow basin: fast and exact); the surface points'
// ICP finds the basin from metres away, as the odometry's ICP does for young maps.
// Deterministic: the registration sums and SDF queries are the same bits for any thread count.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "shine/model/neural_sdf.hpp"
#include "shine/odometry/point_to_plane_icp.hpp"
#include "shine/odometry/registration_solver.hpp"

namespace shine {

/// Settings of localisation in a saved map. YAML: the `localize:` section.
struct LocalizeConfig {
    /// Registration points (sensor frame): range window and one point per voxel.
    double voxel_size_m = 0.5;
    double min_range_m = 1.5;
    double max_range_m = 60.0;
    /// At most this many registration points (every k-th of the voxel selection): time per
    /// scan grows with the points.
    int max_points = 1000;
    /// The recovery and the search (steps 4-5) take up to this many of the same points.
    int recovery_max_points = 2000;
    /// Step 2's starts: the last motion scaled by each of these (1: constant velocity, first; 0:
    /// the last pose), each turned about the vertical by every multiple of start_yaw_step_deg up
    /// to start_yaw_range_deg (0: not turned). The best-scored start is tracked, then the
    /// constant-velocity prediction itself if that fails.
    std::vector<double> start_motion_scales = {1.0, 0.5, 2.0, 0.0};
    double start_yaw_range_deg = 10.0;
    double start_yaw_step_deg = 2.5;
    /// A prediction scoring at least this is tracked without scoring the other starts (1: always
    /// score them all).
    double prediction_good_score = 0.55;
    /// A best start scoring below this goes to the recovery (step 4) without tracking: its
    /// points are too far off the surface for the SDF's basin (0: always track first).
    double track_min_start_score = 0.3;
    /// Geman-McClure kernel scales of the coarse-to-fine stages, m (decreasing).
    std::vector<double> kernel_scales_m = {0.2, 0.05};
    int max_iterations = 20;  ///< per stage
    double max_condition_number = 1e4;
    /// Step 3: a localised scan has at least this share of its registration points within
    /// inlier_distance_m of the surface (|SDF|, inside the map's finest level).
    double inlier_distance_m = 0.1;
    double min_inlier_ratio = 0.8;
    /// Step 4: ICP against the map's surface, baked at this voxel size (m).
    double surface_voxel_m = 0.2;
    double icp_coarse_correspondence_m = 8.0;
    double icp_correspondence_m = 1.0;
    double icp_kernel_scale_m = 0.2;
    double icp_min_inlier_ratio = 0.85;
    /// Each ICP stage stops when an iteration moves the pose less than these. The SDF
    /// registration that follows ICP finishes the pose (its basin is 0.25 m and 2 degrees wide),
    /// so ICP need not converge to the millimetre: 1 cm and 1 mrad (0.06 degrees) took a tenth
    /// off a recovered walk scan against 1 mm and 0.1 mrad, with the same poses.
    double icp_converged_translation_m = 0.01;
    double icp_converged_rotation_rad = 1e-3;
    /// The surface's nearest points looked up by voxel (VoxelNearestLookup) for the fine stage
    /// (within icp_correspondence_m) and the coarse one (icp_coarse_correspondence_m), voxels of
    /// these sizes; 0: searched in the k-d tree (exact, several times slower).
    double icp_lookup_voxel_m = 0.25;
    double icp_coarse_lookup_voxel_m = 0.5;
    /// Step 4-5: headings tried, 360/N degrees apart.
    int search_headings = 12;
    /// Step 5: the global search around the map's places.
    double search_radius_m = 1.0;   ///< horizontal offsets up to this, on a grid
    double search_spacing_m = 1.0;  ///< of this spacing
    /// Without the map\'s trajectory: around the prediction and the last localised pose, this far.
    double lost_search_radius_m = 4.0;
    int search_points = 300;       ///< points that score a candidate
    int search_registrations = 8;  ///< best-scored candidates registered
    /// When those fail on the first scan of a run of failures, the candidates ranked after them
    /// up to this many are registered too (once a run: a drive that leaves the map pays it once).
    /// The scores of a 1 m grid rank the candidate inside ICP's basin low where the scan turned
    /// far: on the real walk's even scans, 3 s apart, scan 46 (40 deg from the scan before) is
    /// found among the best 64, not the best 32 (docs/localize.md). 0 or search_registrations:
    /// no deeper search.
    int deep_search_registrations = 64;
    double place_spacing_m = 1.0;  ///< the map's trajectory thinned to places this far apart
    int global_search_after_failures = 1;
};

/// Throws ConfigError naming the localize.* key of an invalid setting.
void validate(const LocalizeConfig& config);

/// How a scan's pose was found.
enum class LocalizeSource : std::uint8_t {
    kTracked,       ///< registration from the prediction (or the initial pose)
    kRecovered,     ///< ICP against the map's surface from the prediction (or headings)
    kGlobalSearch,  ///< the search around the map's places
    kPrediction,    ///< not localised: the prediction bridges it
};

/// "tracked" / "recovered" / "global-search" / "prediction".
const char* to_string(LocalizeSource source);

/// Where a scan's time went (seconds, steady clock). selection + tracking + recovery + search is
/// about the record's `seconds` (a scan not localised is scored once more at the prediction); the
/// last three are parts of tracking, recovery and search, summed over all three.
struct LocalizeStageSeconds {
    double selection = 0.0;    ///< range window, voxel thinning and the strides
    double starts = 0.0;       ///< step 2's starts scored
    double tracking = 0.0;     ///< steps 2-3 from the prediction, the acceptance check included
    double recovery = 0.0;     ///< step 4 after a failed tracking, its SDF registration included
    double search = 0.0;       ///< step 5, its candidates' scores, ICP and SDF registrations
    double sdf_queries = 0.0;  ///< the SDF registrations' field evaluations (value and gradient)
    double acceptance = 0.0;   ///< step 3's share of points near the surface
    double icp = 0.0;          ///< ICP against the surface and its share of points on a plane
};

/// What localisation did with one scan.
struct LocalizeRecord {
    Eigen::Isometry3d T_world_sensor = Eigen::Isometry3d::Identity();
    LocalizeSource source = LocalizeSource::kPrediction;
    bool localized = false;
    std::uint64_t points = 0;        ///< registration points
    std::uint64_t valid_points = 0;  ///< of them inside the map's finest level, at the pose
    double inlier_ratio = 0.0;       ///< step 3's share at the pose
    double residual_m = 0.0;         ///< median |SDF| of the valid points at the pose
    double condition_number = 0.0;   ///< of the last registration kept (0: none)
    RegistrationStatus status = RegistrationStatus::kTooFewPoints;
    std::int32_t iterations = 0;  ///< over all registrations of the scan
    std::int32_t candidates = 0;  ///< poses scored by a search (0: no search)
    /// The start tracking began from: the motion's scale and the turn (degrees) about the
    /// vertical of the best-scored start (1 and 0: the constant-velocity prediction).
    double start_motion_scale = 1.0;
    double start_yaw_deg = 0.0;
    double start_score = 0.0;       ///< its score (surface_scores)
    double prediction_score = 0.0;  ///< the constant-velocity prediction's score
    double seconds = 0.0;           ///< selection, registration and search
    LocalizeStageSeconds stage_seconds;
};

/// Localises scan after scan in `sdf`, which it only reads.
class MapLocalizer {
  public:
    /// Bakes the map's surface for step 4 (seconds for a large map). Throws DataError for a map
    /// without a surface. `places_world`: poses of the map's trajectory (T_world_sensor) around
    /// which the global search looks; empty: around the initial pose only. Keeps a reference to
    /// `sdf`.
    MapLocalizer(const NeuralSdf& sdf, const LocalizeConfig& config,
                 std::vector<Eigen::Isometry3d> places_world = {});
    ~MapLocalizer();
    /// Points of the surface step 4 registers to.
    std::size_t surface_points() const { return surface_->size(); }

    /// The first scan starts from `T_world_sensor` (tracked) instead of a global search.
    void set_initial_pose(const Eigen::Isometry3d& T_world_sensor);

    /// Localises the next scan (points in the sensor frame) and returns its record.
    const LocalizeRecord& localize(const std::vector<Eigen::Vector3f>& points_sensor);

    const std::vector<LocalizeRecord>& records() const { return records_; }
    /// The places of the global search, thinned (world frame).
    const std::vector<Eigen::Isometry3d>& places() const { return places_; }
    const LocalizeConfig& config() const { return config_; }

  private:
    struct Attempt;
    Attempt track(const std::vector<Eigen::Vector3f>& points, const Eigen::Isometry3d& start) const;
    /// ICP against the surface from `start` (and, when that leaves too few points on a plane,
    /// from `headings_from` turned to each heading), then track() from the best ICP pose.
    /// ICP registers `points`, the SDF `track_points` (tracking's fewer points).
    Attempt recover(const std::vector<Eigen::Vector3f>& points,
                    const std::vector<Eigen::Vector3f>& track_points,
                    const Eigen::Isometry3d& start, const Eigen::Isometry3d* headings_from) const;
    /// Mean over `sample` of max(0, 1 - |SDF| / 2 inlier_distance_m) inside the map, per
    /// candidate pose (the global search's and the starts' score).
    std::vector<double> surface_scores(const std::vector<Eigen::Vector3f>& sample,
                                       const std::vector<Eigen::Isometry3d>& candidates) const;
    /// The global search around `centres`: the best search_registrations candidates registered;
    /// when none localises and `deep_registrations` is larger, the ones ranked after them up to
    /// it (the same candidates and scores), whose best is then returned.
    Attempt search(const std::vector<Eigen::Vector3f>& points,
                   const std::vector<Eigen::Vector3f>& track_points,
                   const std::vector<Eigen::Isometry3d>& centres, double radius_m,
                   int deep_registrations) const;
    /// Share of points within inlier_distance_m of the surface at `pose`, valid count and the
    /// median |SDF| of the valid ones.
    void score(const std::vector<Eigen::Vector3f>& points, const Eigen::Isometry3d& pose,
               double& inlier_ratio, std::size_t& valid, double& residual_m) const;
    /// score()'s figures from the |SDF| of the valid ones of `points` points (reordered).
    void summarise(std::vector<float>& abs_residuals_m, std::size_t points, double& inlier_ratio,
                   std::size_t& valid, double& residual_m) const;
    Eigen::Isometry3d prediction() const;

    const NeuralSdf& sdf_;
    LocalizeConfig config_;
    std::vector<Eigen::Isometry3d> places_;
    std::unique_ptr<ReferencePlanes> surface_;  ///< step 4's reference
    bool has_initial_pose_ = false;
    Eigen::Isometry3d initial_pose_ = Eigen::Isometry3d::Identity();
    std::vector<LocalizeRecord> records_;
    int failures_in_a_row_ = 0;
    /// The scan being localised's stage times (added to by the const steps).
    mutable LocalizeStageSeconds stage_seconds_;
};

}  // namespace shine
