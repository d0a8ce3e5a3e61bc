// Training samples along rays: projective labels on known rays, and labels from surface normals.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "shine/sampling/ray_sampler.hpp"
#include "shine/sampling/ray_set.hpp"
#include "shine/sampling/surface_normals.hpp"

using namespace shine;

TEST(RaySampler, LabelsAreProjectiveDistancesOnAKnownRay) {
    const Eigen::Vector3f origin(1.0f, 2.0f, 3.0f);
    const Eigen::Vector3f direction = Eigen::Vector3f(3.0f, 4.0f, 0.0f).normalized();
    const float range_m = 20.0f;
    const Eigen::Vector3f endpoint = origin + range_m * direction;
    SamplingConfig config;  // surface samples within +-0.3 m, free ones from 0.3 r
    config.surface_samples = 3;
    config.free_samples = 3;
    Pcg32 rng(7);
    for (int trial = 0; trial < 100; ++trial) {
        RaySample samples[6];
        sample_ray(origin, endpoint, Eigen::Vector3f::Zero(), config, rng, samples);
        for (int i = 0; i < config.samples_per_ray(); ++i) {
            const RaySample& s = samples[i];
            const float t = (s.point_map - origin).dot(direction);
            // On the ray, and labelled with the distance still to go to the endpoint.
            EXPECT_LT(((s.point_map - origin) - t * direction).norm(), 1e-4f);
            EXPECT_NEAR(s.sdf_label_m, range_m - t, 1e-4f);
            if (i < config.surface_samples) {
                EXPECT_EQ(s.kind, SampleKind::kSurface);
                EXPECT_LE(std::abs(s.sdf_label_m), config.surface_band_m + 1e-4f);
            } else {
                EXPECT_EQ(s.kind, SampleKind::kFreeSpace);
                EXPECT_GE(t, config.free_space_start_ratio * range_m - 1e-4f);
                EXPECT_GE(s.sdf_label_m, config.surface_band_m - 1e-4f);
            }
        }
    }
}

TEST(RaySampler, WithANormalLabelsAreTangentPlaneDistances) {
    // Ground z = 0 seen 25 m away from 1.7 m high: cos(incidence) = 1.7 / |ray|.
    const Eigen::Vector3f origin(0.0f, 0.0f, 1.7f);
    const Eigen::Vector3f endpoint(25.0f, 0.0f, 0.0f);
    const Eigen::Vector3f up = Eigen::Vector3f::UnitZ();
    const float cosine = 1.7f / (endpoint - origin).norm();
    for (bool along_normal : {true, false}) {
        SamplingConfig config;
        config.surface_samples_along_normal = along_normal;
        Pcg32 rng(3);
        for (int trial = 0; trial < 50; ++trial) {
            RaySample samples[6];
            sample_ray(origin, endpoint, up, config, rng, samples);
            for (int i = 0; i < config.samples_per_ray(); ++i) {
                const RaySample& s = samples[i];
                if (s.kind == SampleKind::kSurface) {
                    // The label is the height above the ground plane, exactly.
                    EXPECT_NEAR(s.sdf_label_m, s.point_map.z(), 1e-5f);
                    EXPECT_LE(std::abs(s.sdf_label_m),
                              config.surface_band_m * (along_normal ? 1.0f : cosine) + 1e-5f);
                    if (along_normal) {
                        EXPECT_NEAR(s.point_map.x(), endpoint.x(), 1e-6f);
                    }
                } else {
                    // Free space: the projective distance times cos(incidence), which for a
                    // plane is again the height above it.
                    EXPECT_NEAR(s.sdf_label_m, s.point_map.z(), 1e-4f);
                }
            }
        }
    }
}

TEST(RaySampler, IncidenceScaleIsClampedForGrazingRays) {
    const Eigen::Vector3f origin(0.0f, 0.0f, 0.1f);
    const Eigen::Vector3f endpoint(50.0f, 0.0f, 0.0f);  // cos = 0.002
    SamplingConfig config;
    config.surface_samples = 0;
    config.free_samples = 3;
    Pcg32 rng(5);
    RaySample samples[3];
    sample_ray(origin, endpoint, Eigen::Vector3f::UnitZ(), config, rng, samples);
    for (const RaySample& s : samples) {
        const float projective = (endpoint - s.point_map).norm();
        EXPECT_NEAR(s.sdf_label_m, config.min_incidence_cosine * projective, 1e-4f);
    }
}

namespace {

/// Endpoints of rays from `origin` to a grid of points on the ground plane z = 0.
RaySet ground_rays(const Eigen::Vector3f& origin, float spacing_m, float extent_m) {
    std::vector<Eigen::Vector3f> endpoints;
    for (float x = -extent_m; x <= extent_m; x += spacing_m) {
        for (float y = -extent_m; y <= extent_m; y += spacing_m) {
            endpoints.emplace_back(x, y, 0.0f);
        }
    }
    RaySet rays;
    rays.add_scan(origin, endpoints);
    return rays;
}

}  // namespace

TEST(SurfaceNormals, PlaneNormalsPointToTheSensor) {
    const Eigen::Vector3f origin(0.0f, 0.0f, 1.7f);
    const RaySet rays = ground_rays(origin, 0.1f, 30.0f);
    const std::vector<Eigen::Vector3f> normals = estimate_ray_normals(rays, NormalConfig{});
    ASSERT_EQ(normals.size(), rays.num_rays());
    double worst = 0.0;
    for (const Eigen::Vector3f& n : normals) {
        worst = std::max(worst, static_cast<double>((n - Eigen::Vector3f::UnitZ()).norm()));
    }
    EXPECT_LT(worst, 1e-4);  // exact plane: PCA recovers the normal to rounding

    // Seen from below, the same plane's normals flip.
    RaySet from_below;
    std::vector<Eigen::Vector3f> endpoints;
    for (std::size_t ray = 0; ray < rays.num_rays(); ++ray) endpoints.push_back(rays.endpoint(ray));
    from_below.add_scan(Eigen::Vector3f(0.0f, 0.0f, -2.0f), endpoints);
    for (const Eigen::Vector3f& n : estimate_ray_normals(from_below, NormalConfig{})) {
        EXPECT_LT((n + Eigen::Vector3f::UnitZ()).norm(), 1e-4f);
    }
}

TEST(SurfaceNormals, NoNormalWhereTheNeighbourhoodIsALineOrTooSparse) {
    // A single scan line (points along x only) has no defined normal.
    std::vector<Eigen::Vector3f> line;
    for (int i = 0; i < 200; ++i) line.emplace_back(0.05f * i, 10.0f, 0.0f);
    RaySet rays;
    rays.add_scan(Eigen::Vector3f(0.0f, 0.0f, 1.7f), line);
    // Two isolated points far from everything: too few neighbours within the radius.
    rays.add_scan(Eigen::Vector3f::Zero(),
                  {Eigen::Vector3f(100.0f, 0.0f, 0.0f), Eigen::Vector3f(0.0f, 100.0f, 0.0f)});
    for (const Eigen::Vector3f& n : estimate_ray_normals(rays, NormalConfig{})) {
        EXPECT_EQ(n, Eigen::Vector3f::Zero());
    }
}

TEST(RaySet, NormalsDefaultToZeroAndMustMatchTheRayCount) {
    RaySet rays;
    rays.add_scan(Eigen::Vector3f::Zero(), {Eigen::Vector3f(1, 0, 0), Eigen::Vector3f(0, 1, 0)});
    EXPECT_EQ(rays.normal(1), Eigen::Vector3f::Zero());
    rays.set_normals({-Eigen::Vector3f::UnitX(), -Eigen::Vector3f::UnitY()});
    EXPECT_EQ(rays.normal(1), -Eigen::Vector3f::UnitY());
    EXPECT_THROW(rays.set_normals({Eigen::Vector3f::UnitX()}), std::exception);
    // Rays added later have no normal.
    rays.add_scan(Eigen::Vector3f::Zero(), {Eigen::Vector3f(0, 0, 1)});
    EXPECT_EQ(rays.normal(2), Eigen::Vector3f::Zero());
    EXPECT_EQ(rays.normal(0), -Eigen::Vector3f::UnitX());
}
