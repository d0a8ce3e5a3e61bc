// Settings of LiDAR odometry while mapping (`shine map --mode incremental --poses estimate`,
// scan_odometry.hpp): which points register, how the solver stops and when it trusts the result.
// The defaults were measured on the simulated street at 0.2 m leaves (docs/odometry.md).
#pragma once

namespace shine {

struct OdometryConfig {
    /// Estimate every scan's pose instead of reading it (incremental mode only). The CLI sets it
    /// for `--poses estimate` and for data without a pose file. YAML: odometry.estimate_poses.
    bool estimate_poses = false;
    /// Registration points: at most one per voxel of this size (sensor frame), within the range
    /// window below (registration_points.hpp). 0.75 m would register a real 64-beam scan in
    /// about half the time (4000 points instead of 6500), but the real walk's estimate drifts
    /// more: its held-out rays at the data's poses fall from 74.1 to 70.5 % within 10 cm
    /// (docs/realtime.md).
    double voxel_size_m = 0.5;
    double min_range_m = 1.5;  ///< closer points do not register (the vehicle itself)
    /// Farther points do not register. Outdoors 30 m, half the mapped range (indoors and on
    /// objects the scene's whole range: not measured there). The map's surface sits about a
    /// millimetre behind a new scan's points (0.1 mm behind the points that trained it), most
    /// where it was seen only from afar, and a scan registered against it sits a fraction of a
    /// millimetre low (against a map trained at a simulated street's true poses 0.70 / 0.54 mm with
    /// 60 m, 0.40 / 0.32 mm with 30 m, seeds 3 / 7). Without poses, 30 m against 60 m: the real
    /// drive's held-out rays at its poses +3.8 points (7 splits of 7 better), the walk's +0.06,
    /// a fifth less registration time; on eight simulated streets the F-score moved by -2.9 to
    /// +2.5 points and -0.04 on average (docs/realtime.md).
    double max_range_m = 30.0;
    /// Levenberg-Marquardt iterations per scan (registration_solver.hpp).
    int max_iterations = 30;
    /// The first icp_warmup_scans scans after the first one register by point-to-plane ICP to
    /// the previous scans' points: the neural map of one or two scans is too young.
    int icp_warmup_scans = 3;
    /// After the warm-up, each scan is first aligned by ICP to the last icp_reference_scans scans
    /// and then refined on the neural map's SDF (one stage, sdf_kernel_scale_m). false: the SDF
    /// registration alone, coarse to fine from the prediction. Measured on the street: the SDF
    /// alone loses track at 2-3 m between scans, ICP first does not (docs/odometry.md).
    bool icp_before_sdf = true;
    /// ICP's reference: the points of this many previous scans (world frame).
    int icp_reference_scans = 3;
    /// ICP: scan points farther than this from every reference point have no match.
    double icp_max_correspondence_m = 1.0;
    /// Geman-McClure scale of ICP's point-to-plane residuals, m.
    double icp_kernel_scale_m = 0.2;
    /// ICP runs coarse to fine: first with matches up to this distance and a kernel of a quarter
    /// of it, then with the two settings above from that result. The second scan starts at rest
    /// (one pose behind it), metres from its pose; 1 m matches alone stop at a wrong minimum
    /// there (measured: 0.4 of 3 m). Keyframes of a walk 2.4-4.4 m apart need 8 m: with 4 m,
    /// three of 35 steps stopped 2.3-4.6 m short (docs/odometry.md); on the street 8 m changes
    /// nothing measurable. 0 (or a value not above icp_max_correspondence_m): one stage.
    double icp_coarse_correspondence_m = 8.0;
    /// When ICP from the prediction leaves fewer than icp_min_inlier_ratio of the registration
    /// points within icp_kernel_scale_m of a reference plane (or is not accepted), it runs again
    /// from the previous pose turned about the world's vertical (z) axis to each of
    /// icp_yaw_hypotheses headings, 360/N degrees apart, and the start with the most inliers
    /// wins. Keyframes of a walk can turn by 9-120 degrees between scans, which a local
    /// registration from the constant-velocity prediction cannot bridge (docs/odometry.md). A
    /// scan that registers well from the prediction, as on a drive at the sensor's frame rate,
    /// costs nothing more. 1: off. A scan ICP registers well leaves 0.8-0.96 of its points on a
    /// plane (the street, the real walk, the 4 km city); in the city's junctions ten scans of
    /// 2501 stopped in a wrong minimum at 0.50-0.66, each turning the estimate 6-11 degrees
    /// (3.3-6.3 % drift with 0.5 here); with 0.7 the headings rescued them (0.03 %).
    int icp_yaw_hypotheses = 12;
    double icp_min_inlier_ratio = 0.7;
    /// Geman-McClure scale of the SDF residuals (the map's SDF at the points), m. Small: points
    /// the map has not seen yet (its untrained margin) must not pull the pose.
    double sdf_kernel_scale_m = 0.02;
    /// Without icp_before_sdf the SDF registration runs coarse to fine as well: first with this
    /// kernel scale, then with sdf_kernel_scale_m. 0 (or a value not above it): one stage.
    double sdf_coarse_kernel_scale_m = 0.1;
    /// Points whose ray meets the map's surface at a grazing angle (|cos| of the angle between
    /// the ray and the SDF's gradient below this) do not register to the SDF
    /// (RegistrationSolverConfig::min_incidence_cosine). With a sensor 1.73 m up, 0.25 leaves out
    /// the road beyond about 7 m, which the map has seen only at grazing angles and from afar;
    /// the near road, walls, cars and poles keep height, pitch and roll. On eight 100-scan
    /// streets without poses the drift fell (unaligned ATE 2.05 -> 1.66 cm on average) and the
    /// F-score rose on seven (+0.34 points on average; docs/realtime.md). 0: every point.
    double sdf_min_incidence_cosine = 0.25;
    /// A solve whose range-scaled Hessian is worse conditioned is not trusted (the prediction is
    /// kept): a single plane or a featureless corridor.
    double max_condition_number = 1e4;
    /// Scans with per-point times (deskewing active) register as measured, the motion during
    /// their sweep estimated together with the pose (continuous time: registration_solver.hpp,
    /// Eq. (3)-(4)), and are mapped deskewed with that motion. The prediction's motion is the
    /// motion between the last two poses, one scan interval stale; where the pose is the sweep's
    /// start (the simulator, many drivers) it misses the sweep by a whole interval
    /// (docs/odometry.md). Used in the registration to the map (after the ICP warm-up); ICP's
    /// stage registers the points deskewed at the prediction's motion. false: register and map
    /// at the prediction's motion and the motion to the estimated pose, as before.
    bool estimate_sweep = true;
    /// Standard deviations of the sweep's motion about the prediction's (Eq. (4)), over one
    /// scan interval: how far the velocity may change from one scan to the next.
    double sweep_prior_translation_m = 0.01;
    double sweep_prior_rotation_deg = 0.1;
    /// The prior's centre (registration_solver.hpp, Eq. (4)-(5)). true ("poses"): the motion
    /// from the previous scan's pose to the pose being solved, one interval's motion for both (the
    /// sweep begins at the previous pose where the pose is the sweep's end, CT-ICP's location
    /// consistency; where it is the sweep's start, the last interval's motion). false
    /// ("prediction"): the constant-velocity prediction's motion, one interval older. On the
    /// distorted streets "poses" lowers the ATE 3.2 -> 2.9 and 4.0 -> 2.7 mm and the rotation
    /// drift by a fifth; the F-scores stay within 0.03 point (docs/odometry.md).
    bool sweep_prior_from_poses = true;
    /// Scans with fewer registration points are not mapped (a warning; their pose is the
    /// prediction).
    int min_scan_points = 100;
};

}  // namespace shine
