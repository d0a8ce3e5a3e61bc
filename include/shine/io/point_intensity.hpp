// Per-point intensity of a scan as stored in a file or message -- the one rule every reader
// (KITTI .bin, PLY, PCD, PointCloud2) applies.
//
// Field: the first of `intensity`, `reflectivity`, `reflectance`, `scalar_intensity`, `i` the
// scan has, compared without case (Velodyne, Hesai, Livox and PCL `intensity`; Ouster
// `reflectivity` besides its `intensity`, which wins; CloudCompare's `scalar_Intensity`; the
// 4th column of a KITTI .bin). Any numeric type, converted to float.
// Units: as the sensor gives them, never rescaled: KITTI's Velodyne reflectances 0..1, a uint8
// field 0..255, Ouster's uint16 up to 65535. Readers do not know the sensor, so values of
// different sensors are not comparable; whoever fuses them must normalise per sensor.
// "No intensity": Scan::intensity empty. A scan whose values are all 0 or not finite carries
// none either: that is what a writer without a measurement puts in a column the format makes
// mandatory (a KITTI .bin's 4th column, ShineVDB's simulator, encoders that pad a field), and
// no sensor reports 0 for every return of a sweep. One non-zero finite value keeps them all,
// zeros included.
// NaN: the point is kept (intensity is not geometry) with its intensity NaN, "unknown for this
// point"; consumers skip non-finite intensities.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace shine {

/// The names read as a per-point intensity, in order of preference (compared without case):
/// intensity, reflectivity, reflectance, scalar_intensity, i.
const std::vector<std::string_view>& intensity_field_names();

/// Index into `field_names` of the intensity field (the first name of intensity_field_names()
/// present, without case), or -1 if there is none.
int find_intensity_field(const std::vector<std::string>& field_names);

/// Whether `intensity` holds a measurement: some value finite and non-zero (file comment).
bool intensity_measured(const std::vector<float>& intensity);

/// Clears `intensity` when it holds no measurement (intensity_measured() false), so that an
/// empty vector is the one way a scan says it has no intensity.
void drop_unmeasured_intensity(std::vector<float>& intensity);

}  // namespace shine
