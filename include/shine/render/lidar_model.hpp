// A spinning LiDAR's own projection, inferred from one of its scans: rings x azimuth columns.
//
// A spinning LiDAR fires a fixed set of beams (rings), each at its own elevation, and sweeps them
// around an axis; its natural image has one row per ring and one column per azimuth step. Given
// only a scan's points in the sensor frame, the model is recovered in three steps:
//   1. the spin axis: scan points may be stored in a frame tilted against the sensor's (an IMU or
//      levelled body frame), where a ring is a cone around a tilted axis. The axis is the one
//      around which the points' elevation angles are sharpest (largest sum of squared histogram
//      counts), found by a coarse-to-fine search over tilts up to max_tilt_deg. Unit directions
//      are smeared by the beam heights (below), which can pull that search a tenth of a degree off
//      an untilted sensor's z and merge rings there; so the rings are found about both the axis
//      found and the sensor's z, and the axis kept is the one whose rings hold the most points
//      within focus_tolerance_deg of their cones (ties keep the axis found);
//   2. the rings: a beam need not leave from the sensor's origin. An HDL-64E's lasers sit 0.12 m
//      (lower block) and 0.21 m (upper block) above it, so each ring is a cone whose apex is on
//      the spin axis at the ring's own beam height h: z = r_xy tan(elevation) + h. Seen from the
//      origin, such a ring's elevation drifts by h / r_xy with range (over a degree within 10 m)
//      and the HDL-64E's upper rings, a third of a degree apart, merge. So the rings are found in
//      a histogram of elevations measured from every candidate beam height (up to
//      max_beam_height_m either way): the tallest peak is a ring seen in focus; it extends from
//      the peak over that row's occupied bins until an empty stretch of min_ring_gap_deg (so a
//      thick ring of a deskewed scan stays whole); its points are taken out and the next peak
//      is sought. Clusters holding fewer than min_ring_share of the median cluster's points are
//      noise (mixed pixels between rings) and dropped; each ring's elevation is its points'
//      median about its beam height. Two rings that mostly hit the ground at one range are sharp
//      from many beam heights and can be bridged by the points between them: a cluster is split
//      at its deepest dip (under a quarter of the smaller side's peak) when both sides hold at
//      least min_ring_share x the median cluster and both go all around (see at least 80 % of
//      the same 1-degree azimuth sectors); a ring smeared by motion is high on one side and low
//      on the other, so its halves see different azimuths and it stays whole;
//   3. the azimuth step: per ring, the median gap between its successive azimuths, ignoring
//      gaps finer than any LiDAR's step (duplicated returns); the median over rings, rounded so a
//      whole number of columns fills the turn.
// Pixels: row 0 is the highest ring; column c looks at azimuth pi - (c + 0.5) * step about the
// axis, so the image centre looks along the sensor's +x (forward), the left edge backwards over
// +y (left): a panorama seen from the sensor. A measured point goes to the ring whose cone
// passes nearest to it (pixel_of_point); a bare direction, or a pixel's centre ray, is the ring
// seen from the origin far away, where beam heights vanish against the range. Points closer than
// min_range_m are not used for inference: the beams' horizontal offsets (and, for the axis
// search, their heights) smear the elevations of close points.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "shine/render/pixel_rays.hpp"

namespace shine {

/// How the beam layout is inferred; the defaults suit 16- to 128-beam spinning LiDARs.
struct SphericalLidarConfig {
    double min_range_m = 2.0;        ///< closer points are not used for inference
    double min_ring_gap_deg = 0.15;  ///< an empty elevation stretch this wide ends a ring
    double min_ring_share = 0.2;     ///< rings with fewer points than this x the median are noise
    double max_tilt_deg = 30.0;      ///< spin-axis search range around sensor z; 0 = sensor z
    double max_beam_height_m = 0.3;  ///< beam-height search range around the origin; 0 = origin
    double beam_height_step_m = 0.005;  ///< step of that search
    std::size_t max_points = 20000;     ///< points used for the axis search (an even subsample)
    /// A point this close to its ring's cone is in focus; the spin axis whose rings hold the most
    /// such points is kept.
    double focus_tolerance_deg = 0.05;
};

/// Rings x columns of a spinning LiDAR, about a spin axis in the sensor frame.
struct SphericalLidarModel {
    /// Columns of R_sensor_beams are the beam frame's axes in the sensor frame; z is the spin axis.
    Eigen::Matrix3d R_sensor_beams = Eigen::Matrix3d::Identity();
    std::vector<double> elevations_rad;  ///< one per ring, row 0 (highest) first, descending
    /// One per ring: where its beams cross the spin axis, above the sensor origin (m).
    std::vector<double> beam_heights_m;
    int num_columns = 0;

    int height() const { return static_cast<int>(elevations_rad.size()); }
    int width() const { return num_columns; }
    /// 2 pi / num_columns.
    double azimuth_step_rad() const;
    /// Tilt of the spin axis from the sensor's z axis (degrees).
    double tilt_deg() const;
    /// Unit ray of pixel (row, col)'s centre, in the sensor frame.
    Eigen::Vector3d direction_sensor(int row, int col) const;
    /// The pixel a direction (any length > 0, sensor frame) falls in: the nearest ring, unless it
    /// is more than half a ring spacing above the top ring or below the bottom one (false).
    bool pixel_of(const Eigen::Vector3d& direction_sensor, int& row, int& col) const;
    /// The pixel of a measured point (sensor frame): as pixel_of, but the nearest ring is the one
    /// whose cone (elevation from its beam height) passes nearest to the point.
    bool pixel_of_point(const Eigen::Vector3d& point_sensor, int& row, int& col) const;
};

/// Infers the model from a scan's points (sensor frame). Throws DataError if fewer than two rings
/// or fewer than 8 (or more than 32768) columns are found (say which and how many points were
/// usable).
SphericalLidarModel infer_spherical_lidar(const std::vector<Eigen::Vector3f>& points_sensor,
                                          const SphericalLidarConfig& config = {});

/// The pixel rays of `model` with the scan's returns: each return whose range is in
/// [min_range_m, max_range_m] goes to its pixel (pixel_of_point; the nearest return wins where
/// several fall in one); a pixel with a return looks along that return's own direction (so its
/// range error is the held-out yardstick's error of that ray), one without along its centre.
PixelRays scan_pixel_rays(const SphericalLidarModel& model,
                          const std::vector<Eigen::Vector3f>& points_sensor, double min_range_m,
                          double max_range_m);

}  // namespace shine
