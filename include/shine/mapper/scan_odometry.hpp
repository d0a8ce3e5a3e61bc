// LiDAR odometry on the neural map: the pose of each new scan, estimated before the scan is
// mapped (`shine map --mode incremental --poses estimate`).
//
// Per scan (estimate):
//   1. the registration points: range window and one point per voxel (registration_points.hpp);
//      a scan with fewer than min_scan_points of them is skipped (not mapped, pose = step 2's);
//   2. the prediction: the first scan stays at its given pose (the identity for data without
//      poses; with poses, the data's first one, so that the map lies in the data's world frame
//      and can be scored against it); the next ones move on at the
//      constant velocity of the last two estimated poses (se3.hpp's predict_constant_velocity;
//      the second scan, with one pose behind it, at rest);
//   3. while the map is young (scans 1 .. icp_warmup_scans) point-to-plane ICP against the points
//      of the last icp_reference_scans scans in the world frame (point_to_plane_icp.hpp), coarse
//      to fine (a wide stage that finds the basin, then a narrow one that ignores what does not
//      fit: odometry_config.hpp); afterwards registration to the neural map's SDF
//      (sdf_registration.hpp through NeuralSdfField), started from that ICP's result
//      (icp_before_sdf, the default: the SDF is metric only near surfaces, so its basin is
//      narrow) or coarse to fine from the prediction;
//   4. a registration to the map that is not accepted (RegistrationResult::accepted) leaves ICP's
//      pose when ICP found its start, else the prediction; the record says which (source) and
//      why (tried, status).
// A scan with per-point times comes with the motion expected during its sweep (SweepPrior: the
// prediction's). ICP registers its points deskewed at that motion; the registration to the map
// takes them as measured and estimates the sweep's motion with the pose (estimate_sweep;
// registration_solver.hpp, Eq. (3)-(4)), which the mapper then deskews the scan with
// (sweep_motion).
// The mapper then maps the scan at the estimated pose. Deterministic: the registration sums are
// the same bits for any thread count.
#pragma once

#include <Eigen/Geometry>
#include <cstdint>
#include <deque>
#include <vector>

#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/odometry_config.hpp"
#include "shine/model/neural_sdf.hpp"
#include "shine/odometry/registration_solver.hpp"

namespace shine {

class BinaryReader;
class BinaryWriter;

/// Where a scan's estimated pose came from.
enum class PoseSource : std::uint8_t {
    kFirst,       ///< the first scan: its given pose (identity without poses), the world frame
    kIcp,         ///< accepted point-to-plane ICP (also when the SDF stage after it was not)
    kSdf,         ///< accepted registration to the neural map
    kPrediction,  ///< no registration was accepted: the constant-velocity prediction
    kSkipped      ///< too few points: not registered, not mapped; pose = the prediction
};

/// "first" / "icp" / "sdf" / "prediction" / "skipped".
const char* to_string(PoseSource source);

/// Which registration was tried (kSdf also when ICP found its start).
enum class RegistrationMethod : std::uint8_t { kNone, kIcp, kSdf };

/// "none" / "icp" / "sdf".
const char* to_string(RegistrationMethod method);

/// What the odometry did with one scan (plain data, stored in checkpoints).
struct OdometryRecord {
    PoseSource source = PoseSource::kFirst;
    RegistrationMethod tried = RegistrationMethod::kNone;
    RegistrationStatus status = RegistrationStatus::kTooFewPoints;  ///< of the last stage
    bool accepted = false;
    std::int32_t iterations = 0;  ///< over all stages
    /// Sum of rho (m^2) at the start and the end of the LAST stage (whose kernel they use).
    double initial_cost = 0.0;
    double final_cost = 0.0;
    double condition_number = 0.0;   ///< of the range-scaled H at the last iterate
    std::uint64_t points = 0;        ///< registration points of the scan
    std::uint64_t valid_points = 0;  ///< of them, with a residual at the last iterate
    /// |log(T_prediction^-1 T_estimate)|: how far the registration moved the pose, m and rad.
    double correction_m = 0.0;
    double correction_rad = 0.0;
    double seconds = 0.0;  ///< selection, reference and registration
    /// ICP's fitness at its result (point_to_plane_inlier_ratio; 0 when ICP did not run), and
    /// how many headings were tried after the prediction's ICP fell short (0: none).
    double icp_inlier_ratio = 0.0;
    std::int32_t yaw_hypotheses = 0;
    /// The motion during the scan's sweep over the prior's interval (a twist: rho m, phi rad):
    /// estimated with the pose when sweep_estimated, else the prior's (zero without one).
    double sweep_twist[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    bool sweep_estimated = false;
};

/// The motion expected during a scan's sweep: `T_expected` over `interval_s` seconds (the
/// constant-velocity prediction's: the motion between the last two poses, scaled to the
/// interval). The scan's point_time_s are seconds relative to its pose (scan_deskew.hpp).
struct SweepPrior {
    Eigen::Isometry3d T_expected = Eigen::Isometry3d::Identity();
    double interval_s = 0.1;
};

/// What a scan's registration finds before it needs the map (steps 1-2 and ICP): made by
/// ScanOdometry::prepare() and ended by finish(), so that the next scan's points and ICP can be
/// prepared while the map still trains on the scan before it.
struct PreparedScan {
    OdometryRecord record;                  ///< filled so far
    std::vector<Eigen::Vector3f> points;    ///< registration points (deskewed with a sweep)
    std::vector<Eigen::Vector3f> measured;  ///< as measured, with a sweep
    SweepModel sweep;
    bool registers = false;   ///< neither the first scan nor skipped: finish() registers it
    bool continuous = false;  ///< the last stage estimates the sweep's motion
    bool icp = false;         ///< ICP's warm-up: no registration to the map
    std::size_t scan = 0;     ///< the scan's number among the odometry's (poses() before it)
    Eigen::Isometry3d prediction = Eigen::Isometry3d::Identity();
    Eigen::Isometry3d sdf_start = Eigen::Isometry3d::Identity();  ///< ICP's pose, or prediction
    bool icp_found_start = false;
    RegistrationResult result;  ///< ICP's last stage
    int iterations = 0;
    double seconds = 0.0;
};

/// The odometry of one run: poses and records of the scans seen so far.
class ScanOdometry {
  public:
    /// Throws ConfigError naming the odometry.* key of an invalid setting.
    explicit ScanOdometry(const OdometryConfig& config);

    /// Estimates the pose of the next scan (`scan.points_sensor`; its own pose is used for the
    /// first scan only, as the world frame's anchor) with
    /// `map` holding the scans estimated before it (steps 1-4 of the file comment). Returns the
    /// record; pose() is the estimate. Call remember_scan() once the scan is mapped. With
    /// `sweep`, the scan is as measured and carries per-point times (file comment); throws
    /// DataError if their count differs from the points'.
    const OdometryRecord& estimate(const Scan& scan, const NeuralSdf& map,
                                   const SweepPrior* sweep = nullptr);

    /// estimate() in two parts: prepare() does what needs no map (it changes nothing and may run
    /// while the map trains on the scan before, once that scan's remember_scan() is done), and
    /// finish() registers to `map` and keeps the pose. finish(scan, prepare(scan, sweep), map)
    /// is estimate(scan, map, sweep), bit for bit. finish() throws std::logic_error if another
    /// scan's pose was kept since `prepared` was made.
    PreparedScan prepare(const Scan& scan, const SweepPrior* sweep = nullptr) const;
    const OdometryRecord& finish(PreparedScan prepared, const NeuralSdf& map);

    /// The first scan's sweep, which no earlier pose gives: from `second`, the next scan,
    /// before `first` is mapped. Both are deskewed at one constant velocity, the motion between
    /// their poses, and the second registered to the first by ICP, until the motion settles.
    /// Sets record 0's sweep (and with it the second scan's prediction) and returns true; false
    /// (nothing changed) unless estimate() has seen only `first`, both carry per-point times
    /// (seconds relative to their poses, `interval_s` apart), estimate_sweep is on and ICP
    /// converged.
    bool bootstrap_sweep(const Scan& first, const Scan& second, double interval_s);

    /// The motion during scan i's sweep over its prior's interval (record i's sweep_twist).
    Eigen::Isometry3d sweep_motion(std::size_t i) const;

    /// Keeps `scan` (at its T_world_sensor) as an ICP reference while ICP scans are still to
    /// come, with the planes of its points fitted now, among its own and the other reference
    /// scans' points (fit_plane_normals), and kept while it is a reference. Called after
    /// estimate() for mapped scans (the time is added to the scan's record), and when resuming
    /// for the replayed ones.
    void remember_scan(const Scan& scan);

    /// Whether the scan of record `i` is to be mapped (not skipped).
    bool mapped(std::size_t i) const { return records_.at(i).source != PoseSource::kSkipped; }
    const std::vector<Eigen::Isometry3d>& poses() const { return poses_; }
    const std::vector<OdometryRecord>& records() const { return records_; }
    const OdometryConfig& config() const { return config_; }

    /// Poses and records for a checkpoint; load() restores them (the ICP reference is rebuilt
    /// by remember_scan() on the replayed scans). load() throws IoError via the reader.
    void save(BinaryWriter& out) const;
    void load(BinaryReader& in);

  private:
    OdometryConfig config_;
    std::vector<Eigen::Isometry3d> poses_;
    std::vector<OdometryRecord> records_;
    /// Registration-thinned points (world frame) of the last icp_reference_scans scans.
    std::deque<std::vector<Eigen::Vector3d>> reference_world_;
    /// Their plane normals (zero: no plane), each scan's fitted when it joined.
    std::deque<std::vector<Eigen::Vector3d>> reference_normals_;
    bool replaying_ = false;  ///< after load(), until the next estimate()
};

}  // namespace shine
