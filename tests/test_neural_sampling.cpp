// Training samples along rays: projective labels on known rays, and the incidence correction.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "shine/sampling/incidence.hpp"
#include "shine/sampling/ray_sampler.hpp"
#include "shine/sampling/ray_set.hpp"

using namespace shine;

TEST(RaySampler, LabelsAreProjectiveDistancesOnAKnownRay) {
    const Eigen::Vector3f origin(1.0f, 2.0f, 3.0f);
    const Eigen::Vector3f direction = Eigen::Vector3f(3.0f, 4.0f, 0.0f).normalized();
    const float range_m = 20.0f;
    const Eigen::Vector3f endpoint = origin + range_m * direction;
    SamplingConfig config;  // 3 surface samples within +-0.3 m, 3 free from 0.3 r
    Pcg32 rng(7);
    for (int trial = 0; trial < 100; ++trial) {
        RaySample samples[6];
        sample_ray(origin, endpoint, config, rng, samples);
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

TEST(RaySampler, LabelScaleMultipliesEveryLabelWithoutMovingSamples) {
    const Eigen::Vector3f origin(0.0f, 0.0f, 1.7f);
    const Eigen::Vector3f endpoint(25.0f, 0.0f, 0.0f);
    SamplingConfig config;
    Pcg32 rng_a(3), rng_b(3);
    RaySample plain[6], scaled[6];
    sample_ray(origin, endpoint, config, rng_a, plain);
    sample_ray(origin, endpoint, config, rng_b, scaled, 0.25f);
    for (int i = 0; i < config.samples_per_ray(); ++i) {
        EXPECT_EQ(plain[i].point_map, scaled[i].point_map);
        EXPECT_FLOAT_EQ(scaled[i].sdf_label_m, 0.25f * plain[i].sdf_label_m);
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

TEST(Incidence, CosineOnAPlaneIsSensorHeightOverRange) {
    const Eigen::Vector3f origin(0.0f, 0.0f, 1.7f);
    const RaySet rays = ground_rays(origin, 0.1f, 30.0f);
    const std::vector<float> cosines = ray_incidence_cosines(rays, IncidenceConfig{});
    ASSERT_EQ(cosines.size(), rays.num_rays());
    double worst = 0.0;
    for (std::size_t ray = 0; ray < rays.num_rays(); ++ray) {
        const Eigen::Vector3f d = rays.endpoint(ray) - origin;
        const float expected = std::max(1.7f / d.norm(), IncidenceConfig{}.min_cosine);
        worst = std::max(worst, static_cast<double>(std::abs(cosines[ray] - expected)));
    }
    EXPECT_LT(worst, 1e-4);  // exact plane: PCA recovers the normal to rounding
}

TEST(Incidence, NoCorrectionWhereTheNeighbourhoodIsALineOrTooSparse) {
    // A single scan line (points along x only) has no defined normal.
    std::vector<Eigen::Vector3f> line;
    for (int i = 0; i < 200; ++i) line.emplace_back(0.05f * i, 10.0f, 0.0f);
    RaySet rays;
    rays.add_scan(Eigen::Vector3f(0.0f, 0.0f, 1.7f), line);
    // Two isolated points far from everything: too few neighbours within the radius.
    rays.add_scan(Eigen::Vector3f::Zero(),
                  {Eigen::Vector3f(100.0f, 0.0f, 0.0f), Eigen::Vector3f(0.0f, 100.0f, 0.0f)});
    for (float c : ray_incidence_cosines(rays, IncidenceConfig{})) EXPECT_EQ(c, 1.0f);
}

TEST(RaySet, LabelScalesDefaultToOneAndMustMatchTheRayCount) {
    RaySet rays;
    rays.add_scan(Eigen::Vector3f::Zero(), {Eigen::Vector3f(1, 0, 0), Eigen::Vector3f(0, 1, 0)});
    EXPECT_EQ(rays.label_scale(1), 1.0f);
    rays.set_label_scales({0.5f, 0.25f});
    EXPECT_EQ(rays.label_scale(1), 0.25f);
    EXPECT_THROW(rays.set_label_scales({0.5f}), std::exception);
    // Rays added later start uncorrected.
    rays.add_scan(Eigen::Vector3f::Zero(), {Eigen::Vector3f(0, 0, 1)});
    EXPECT_EQ(rays.label_scale(2), 1.0f);
    EXPECT_EQ(rays.label_scale(0), 0.5f);
}
