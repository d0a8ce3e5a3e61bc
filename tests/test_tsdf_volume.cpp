// TSDF integration (VDBFusion's algorithm) checked against values computed by hand, and the ray
// walk against a brute-force list of the voxels a segment crosses.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>
#include <tuple>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/tsdf/tsdf_volume.hpp"

using namespace shine;

namespace {

constexpr double kVoxelM = 0.1;
constexpr double kTruncM = 0.3;
constexpr float kValueTol = 1e-6f;  // float rounding of values of order 0.1 m

TsdfConfig config(bool carving = false) {
    TsdfConfig c;
    c.voxel_size_m = kVoxelM;
    c.trunc_m = kTruncM;
    c.space_carving = carving;
    return c;
}

// A ray along +x through the centres of the voxels (i, 0, 0): origin inside voxel 0, at
// x = 0.02 m; voxel i has its centre at x = (i + 0.5) * 0.1 m.
const Eigen::Vector3d kOrigin(0.02, 0.05, 0.05);
Eigen::Vector3d point_at_x(double x) { return {x, 0.05, 0.05}; }
openvdb::Coord voxel_x(int i) { return openvdb::Coord(i, 0, 0); }

}  // namespace

TEST(TsdfPointSdf, SignedByWhetherTheCentreIsBeforeOrBehindThePoint) {
    const Eigen::Vector3d o(0, 0, 0), p(1, 0, 0);
    EXPECT_NEAR(point_sdf_m(o, p, {0.5, 0, 0}), 0.5f, kValueTol);
    EXPECT_NEAR(point_sdf_m(o, p, {1.2, 0, 0}), -0.2f, kValueTol);
    // Off the ray: Euclidean distance to the point, not the distance along the ray.
    EXPECT_NEAR(point_sdf_m(o, p, {0.7, 0.4, 0}), 0.5f, kValueTol);  // |(0.3, -0.4)| = 0.5
    // (c - o) . (p - c) = (1, 0.1) . (0, -0.1) < 0: counted as behind the point.
    EXPECT_NEAR(point_sdf_m(o, p, {1.0, 0.1, 0}), -0.1f, kValueTol);
    EXPECT_EQ(point_sdf_m(o, p, p), 0.0f);
}

TEST(TsdfConfigCheck, RejectsNonPositiveSizes) {
    TsdfConfig c = config();
    c.voxel_size_m = 0.0;
    try {
        TsdfVolume v(c);
        FAIL() << "no error for voxel size 0";
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("--voxel-size-m"), std::string::npos) << e.what();
    }
    c = config();
    c.trunc_m = -1.0;
    EXPECT_THROW(TsdfVolume{c}, ConfigError);
}

TEST(TsdfIntegrate, OneRayUpdatesTheBandOnly) {
    TsdfVolume volume(config());
    // Point at x = 1.06 m: depth 1.04 m, the band t in [0.74, 1.34] covers x in [0.76, 1.36], so
    // the DDA visits voxels 7 (entered at t0) to 13 (entered at x = 1.3 <= 1.36).
    const std::size_t updates = volume.integrate({point_at_x(1.06)}, kOrigin);
    // sdf = 1.06 - centre, clamped to +0.3; voxel 13 (centre 1.35, sdf -0.29) is still > -0.3.
    const float expected[] = {0.3f /* 0.31 clamped */, 0.21f, 0.11f, 0.01f, -0.09f, -0.19f, -0.29f};
    for (int i = 7; i <= 13; ++i) {
        EXPECT_NEAR(volume.tsdf(voxel_x(i)), expected[i - 7], kValueTol) << "voxel " << i;
        EXPECT_EQ(volume.weight(voxel_x(i)), 1.0f) << "voxel " << i;
    }
    EXPECT_EQ(updates, 7u);
    EXPECT_EQ(volume.active_voxels(), 7u);
    for (int i : {-1, 0, 6, 14}) EXPECT_EQ(volume.weight(voxel_x(i)), 0.0f) << "voxel " << i;
    EXPECT_EQ(volume.tsdf(voxel_x(6)), static_cast<float>(kTruncM));  // background
}

TEST(TsdfIntegrate, SecondRayAveragesAndSkipsVoxelsBeyondTheTruncation) {
    TsdfVolume volume(config());
    volume.integrate({point_at_x(1.06)}, kOrigin);
    // Point at x = 1.02: band x in [0.72, 1.32], voxels 7..13; voxel 13 (centre 1.35) has
    // sdf -0.33 <= -0.3 and is not updated (VDBFusion's sdf > -trunc rule).
    const std::size_t updates = volume.integrate({point_at_x(1.02)}, kOrigin);
    EXPECT_EQ(updates, 6u);
    const float second[] = {0.27f, 0.17f, 0.07f, -0.03f, -0.13f, -0.23f};
    const float first[] = {0.3f, 0.21f, 0.11f, 0.01f, -0.09f, -0.19f};
    for (int i = 7; i <= 12; ++i) {
        EXPECT_NEAR(volume.tsdf(voxel_x(i)), 0.5f * (first[i - 7] + second[i - 7]), kValueTol)
            << "voxel " << i;
        EXPECT_EQ(volume.weight(voxel_x(i)), 2.0f) << "voxel " << i;
    }
    EXPECT_NEAR(volume.tsdf(voxel_x(13)), -0.29f, kValueTol);
    EXPECT_EQ(volume.weight(voxel_x(13)), 1.0f);
}

TEST(TsdfIntegrate, TwoPointsOfOneScanUpdateAVoxelTwiceInOrder) {
    TsdfVolume one_scan(config()), two_scans(config());
    one_scan.integrate({point_at_x(1.06), point_at_x(1.02)}, kOrigin);
    two_scans.integrate({point_at_x(1.06)}, kOrigin);
    two_scans.integrate({point_at_x(1.02)}, kOrigin);
    for (int i = 0; i <= 14; ++i) {
        EXPECT_EQ(one_scan.tsdf(voxel_x(i)), two_scans.tsdf(voxel_x(i))) << "voxel " << i;
        EXPECT_EQ(one_scan.weight(voxel_x(i)), two_scans.weight(voxel_x(i))) << "voxel " << i;
    }
    EXPECT_EQ(one_scan.weight(voxel_x(10)), 2.0f);
}

TEST(TsdfIntegrate, SpaceCarvingUpdatesEveryVoxelFromTheSensor) {
    TsdfVolume volume(config(/*carving=*/true));
    // Point at x = 1.02: depth 1.0, t in [0, 1.3] covers voxels 0..13.
    const std::size_t updates = volume.integrate({point_at_x(1.02)}, kOrigin);
    for (int i = 0; i <= 6; ++i) {
        EXPECT_EQ(volume.weight(voxel_x(i)), 1.0f) << "voxel " << i;
        EXPECT_EQ(volume.tsdf(voxel_x(i)), 0.3f) << "voxel " << i;  // far in front: clamped
    }
    const float band[] = {0.27f, 0.17f, 0.07f, -0.03f, -0.13f, -0.23f};
    for (int i = 7; i <= 12; ++i) {
        EXPECT_NEAR(volume.tsdf(voxel_x(i)), band[i - 7], kValueTol) << "voxel " << i;
        EXPECT_EQ(volume.weight(voxel_x(i)), 1.0f) << "voxel " << i;
    }
    EXPECT_EQ(volume.weight(voxel_x(13)), 0.0f);  // sdf -0.33: not updated
    EXPECT_EQ(volume.weight(voxel_x(-1)), 0.0f);  // behind the sensor
    EXPECT_EQ(updates, 13u);
    // VDBFusion's background with space carving is -trunc.
    EXPECT_EQ(volume.tsdf(voxel_x(20)), -0.3f);
}

TEST(TsdfIntegrate, DiagonalRayVisitsExactlyTheVoxelsTheSegmentCrosses) {
    TsdfVolume volume(config(/*carving=*/true));
    const Eigen::Vector3d origin(0.013, -0.027, 0.041);
    const Eigen::Vector3d point(2.371, 1.093, -0.687);
    volume.integrate({point}, origin);
    // Brute force: sample the segment [origin, point + trunc * direction] densely.
    const Eigen::Vector3d direction = (point - origin).normalized();
    const double length = (point - origin).norm() + kTruncM;
    std::set<std::tuple<int, int, int>> crossed;
    constexpr int kSamples = 200000;  // 13 um apart: far below the voxel size
    for (int s = 0; s <= kSamples; ++s) {
        const openvdb::Coord c = volume.voxel_of(origin + direction * (length * s / kSamples));
        const float sdf = point_sdf_m(origin, point, volume.voxel_centre_map(c));
        if (sdf > -kTruncM) crossed.insert({c.x(), c.y(), c.z()});
    }
    std::set<std::tuple<int, int, int>> updated;
    for (auto it = volume.weight_grid().cbeginValueOn(); it; ++it) {
        EXPECT_EQ(*it, 1.0f);
        updated.insert({it.getCoord().x(), it.getCoord().y(), it.getCoord().z()});
    }
    EXPECT_EQ(updated, crossed);
    EXPECT_GT(updated.size(), 40u);
}

TEST(TsdfIntegrate, PlaneSeenHeadOnGivesItsExactSignedDistance) {
    // A plane x = 2.02 m seen head-on by an 11 x 11 grid of rays, one through the centre of each
    // voxel column (j, k), from a sensor 102 m away: the rays are parallel to x to within 0.3 mrad,
    // so each column is updated by its own ray only, and the stored value must be the plane's
    // signed distance 2.02 - x at every voxel centre of the band (the lateral drift of a ray
    // across the band, at most 1.5 mm, changes the distance to its point by under 0.05 mm).
    TsdfVolume volume(config());
    const Eigen::Vector3d sensor(-100.0, 0.05, 0.05);
    constexpr double kPlaneX = 2.02;
    constexpr int kHalf = 5;
    std::vector<Eigen::Vector3d> points;
    for (int j = -kHalf; j <= kHalf; ++j) {
        for (int k = -kHalf; k <= kHalf; ++k) {
            points.emplace_back(kPlaneX, 0.05 + kVoxelM * j, 0.05 + kVoxelM * k);
        }
    }
    volume.integrate(points, sensor);
    // The band x in [1.72, 2.32] covers voxels 17 (centre 1.75) to 23 (centre 2.35, entered at
    // 2.3); 23's distance -0.33 is beyond the truncation, so it is visited but not updated.
    std::size_t checked = 0;
    for (int j = -kHalf; j <= kHalf; ++j) {
        for (int k = -kHalf; k <= kHalf; ++k) {
            for (int i = 17; i <= 22; ++i) {
                const openvdb::Coord voxel(i, j, k);
                const double exact = kPlaneX - volume.voxel_centre_map(voxel).x();
                EXPECT_NEAR(volume.tsdf(voxel), exact, 1e-4) << voxel;
                EXPECT_EQ(volume.weight(voxel), 1.0f) << voxel;
                ++checked;
            }
            EXPECT_EQ(volume.weight(openvdb::Coord(16, j, k)), 0.0f);
            EXPECT_EQ(volume.weight(openvdb::Coord(23, j, k)), 0.0f);
        }
    }
    EXPECT_EQ(checked, 121u * 6u);
    EXPECT_EQ(volume.active_voxels(), 121u * 6u);
}

TEST(TsdfIntegrate, SkipsNonFinitePointsAndPointsAtTheSensor) {
    TsdfVolume volume(config());
    const double nan = std::numeric_limits<double>::quiet_NaN();
    EXPECT_EQ(volume.integrate({Eigen::Vector3d(nan, 0, 0), kOrigin}, kOrigin), 0u);
    EXPECT_TRUE(volume.empty());
    EXPECT_THROW(volume.integrate({point_at_x(1.0)}, Eigen::Vector3d(nan, 0, 0)), DataError);
}

TEST(TsdfVolumeFrame, GridTransformPlacesVoxelCentresInTheWorld) {
    const Eigen::Vector3d origin_world(500000.0, 4100000.0, 0.0);
    TsdfVolume volume(config(), origin_world);
    const openvdb::Vec3d centre = volume.tsdf_grid().indexToWorld(openvdb::Coord(3, -2, 7));
    EXPECT_NEAR(centre.x(), 500000.35, 1e-6);
    EXPECT_NEAR(centre.y(), 4099999.85, 1e-6);
    EXPECT_NEAR(centre.z(), 0.75, 1e-6);
    EXPECT_EQ(volume.voxel_of(Eigen::Vector3d(0.35, -0.15, 0.75)), openvdb::Coord(3, -2, 7));
    volume.integrate({point_at_x(1.06)}, kOrigin);
    EXPECT_THROW(volume.set_origin_world_m(Eigen::Vector3d::Zero()), std::logic_error);
}
