// A spinning LiDAR's own projection, inferred from one of its scans: rings x azimuth columns.
//
// A spinning LiDAR fires a fixed set of beams (rings), each at its own elevation, and sweeps them
// around an axis; its natural image has one row per ring and one column per azimuth step. Given
// only a scan's points in the sensor frame, the model is recovered in three steps:
//   1. the spin axis: scan points may be stored in a frame tilted against the sensor's (an IMU or
//      levelled body frame), where a ring is a cone around a tilted axis. The axis is the one
//      around which the points' elevation angles are sharpest (largest sum of squared histogram
//      counts), found by a coarse-to-fine search over tilts up to max_tilt_deg;
//   2. the rings: the points' elevations about that axis, sorted, split wherever two neighbours
//      differ by more than min_ring_gap_deg; clusters holding fewer than min_ring_share of the
//      median cluster's points are noise (mixed pixels between rings) and dropped; each ring's
//      elevation is its cluster's median;
//   3. the azimuth step: the median gap between successive azimuths within a ring, rounded so a
//      whole number of columns fills the turn.
// Pixels: row 0 is the highest ring; column c looks at azimuth pi - (c + 0.5) * step about the
// axis, so the image centre looks along the sensor's +x (forward), the left edge backwards over
// +y (left): a panorama seen from the sensor. Points closer than min_range_m are not used for
// inference, since the beams' origin offsets smear the elevations of close points.
#pragma once

#include <Eigen/Core>
#include <vector>

#include "shine/render/pixel_rays.hpp"

namespace shine {

/// How the beam layout is inferred; the defaults suit 16- to 128-beam spinning LiDARs.
struct SphericalLidarConfig {
    double min_range_m = 2.0;        ///< closer points are not used for inference
    double min_ring_gap_deg = 0.15;  ///< sorted elevations further apart start a new ring
    double min_ring_share = 0.2;     ///< rings with fewer points than this x the median are noise
    double max_tilt_deg = 30.0;      ///< spin-axis search range around sensor z; 0 = sensor z
    std::size_t max_points = 20000;  ///< points used for the axis search (an even subsample)
};

/// Rings x columns of a spinning LiDAR, about a spin axis in the sensor frame.
struct SphericalLidarModel {
    /// Columns of R_sensor_beams are the beam frame's axes in the sensor frame; z is the spin axis.
    Eigen::Matrix3d R_sensor_beams = Eigen::Matrix3d::Identity();
    std::vector<double> elevations_rad;  ///< one per ring, row 0 (highest) first, descending
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
};

/// Infers the model from a scan's points (sensor frame). Throws DataError if fewer than two rings
/// or fewer than 8 columns are found (say which and how many points were usable).
SphericalLidarModel infer_spherical_lidar(const std::vector<Eigen::Vector3f>& points_sensor,
                                          const SphericalLidarConfig& config = {});

/// The pixel rays of `model` with the scan's returns: each return whose range is in
/// [min_range_m, max_range_m] goes to its pixel (the nearest return wins where several fall in
/// one); a pixel with a return looks along that return's own direction (so its range error is the
/// held-out yardstick's error of that ray), one without along its centre.
PixelRays scan_pixel_rays(const SphericalLidarModel& model,
                          const std::vector<Eigen::Vector3f>& points_sensor, double min_range_m,
                          double max_range_m);

}  // namespace shine
