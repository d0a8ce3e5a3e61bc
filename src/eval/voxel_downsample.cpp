#include "shine/eval/voxel_downsample.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <tuple>

#include "shine/core/error.hpp"

namespace shine {
namespace voxel_downsample_internal {

/// A point with the integer index of its voxel; sorting these groups each voxel's points.
struct KeyedPoint {
    std::array<std::int32_t, 3> voxel;
    Eigen::Vector3f point;
};

/// Orders by voxel, then by coordinates, so that the order inside a voxel (and with it the
/// floating-point summation order of the centroid) does not depend on the parallel sort.
bool operator<(const KeyedPoint& a, const KeyedPoint& b) {
    if (a.voxel != b.voxel) return a.voxel < b.voxel;
    return std::tie(a.point.x(), a.point.y(), a.point.z()) <
           std::tie(b.point.x(), b.point.y(), b.point.z());
}

}  // namespace voxel_downsample_internal

std::vector<Eigen::Vector3f> voxel_downsample_centroids(const std::vector<Eigen::Vector3f>& points,
                                                        double voxel_size_m) {
    using voxel_downsample_internal::KeyedPoint;
    if (!(voxel_size_m > 0.0) || !std::isfinite(voxel_size_m)) {
        throw DataError("voxel size " + std::to_string(voxel_size_m) +
                        " m is invalid; it must be positive and finite");
    }
    const double inv_size = 1.0 / voxel_size_m;
    constexpr double kMaxIndex = static_cast<double>(std::numeric_limits<std::int32_t>::max());

    std::vector<KeyedPoint> keyed(points.size());
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, points.size()),
        [&](const tbb::blocked_range<std::size_t>& range) {
            for (std::size_t i = range.begin(); i != range.end(); ++i) {
                const Eigen::Vector3f& p = points[i];
                KeyedPoint& k = keyed[i];
                k.point = p;
                for (int axis = 0; axis < 3; ++axis) {
                    const double index = std::floor(static_cast<double>(p[axis]) * inv_size);
                    if (!(std::abs(index) < kMaxIndex)) {  // also catches NaN and infinity
                        throw DataError("point " + std::to_string(i) + " has coordinate " +
                                        std::to_string(p[axis]) + " m, which is not finite or " +
                                        "too far from the origin for voxels of " +
                                        std::to_string(voxel_size_m) + " m");
                    }
                    k.voxel[axis] = static_cast<std::int32_t>(index);
                }
            }
        });
    tbb::parallel_sort(keyed.begin(), keyed.end());

    std::vector<Eigen::Vector3f> centroids;
    for (std::size_t begin = 0; begin < keyed.size();) {
        std::size_t end = begin;
        Eigen::Vector3d sum = Eigen::Vector3d::Zero();
        while (end < keyed.size() && keyed[end].voxel == keyed[begin].voxel) {
            sum += keyed[end].point.cast<double>();
            ++end;
        }
        centroids.push_back((sum / static_cast<double>(end - begin)).cast<float>());
        begin = end;
    }
    return centroids;
}

}  // namespace shine
