// Forgetting on a small two-region scene (the paper's Fig. 3 situation): region A (ground and a
// sphere) is scanned from close by first; then the sensor drives on to region B (ground and a
// box), from where it still sees A's ground, but only far away and at grazing angles, a few scan
// lines per scan. Training on those scans alone retrains the rows A's well-observed surface
// depends on: without the importance-weight regulariser A's SDF error grows; with it, it stays.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "shine/mapper/incremental_mapper.hpp"

using namespace shine;

namespace {

const Eigen::Vector3d kSphereCentre(0.0, 2.2, 0.9);
constexpr double kSphereRadiusM = 0.9;
const Eigen::Vector3d kBoxMin(6.5, 1.5, 0.0), kBoxMax(8.5, 3.5, 2.0);

double box_sdf(const Eigen::Vector3d& p) {
    const Eigen::Vector3d centre = 0.5 * (kBoxMin + kBoxMax), half = 0.5 * (kBoxMax - kBoxMin);
    const Eigen::Vector3d q = (p - centre).cwiseAbs() - half;
    return q.cwiseMax(0.0).norm() + std::min(q.maxCoeff(), 0.0);
}

double scene_sdf(const Eigen::Vector3d& p) {
    return std::min({p.z(), (p - kSphereCentre).norm() - kSphereRadiusM, box_sdf(p)});
}

// Closest hit along a unit ray, or a negative value (sphere tracing on the exact SDF).
double cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d, double max_m) {
    double t = 0.0;
    for (int i = 0; i < 400 && t < max_m; ++i) {
        const double s = scene_sdf(o + t * d);
        if (s < 1e-5) return t;
        t += s;
    }
    return -1.0;
}

Scan make_scan(const Eigen::Vector3d& origin, double max_range_m) {
    constexpr int kBeams = 24, kAzimuths = 540;
    Scan scan;
    scan.T_world_sensor.translation() = origin;
    for (int b = 0; b < kBeams; ++b) {
        const double elevation = (-35.0 + 33.0 * b / (kBeams - 1)) * M_PI / 180.0;
        for (int a = 0; a < kAzimuths; ++a) {
            const double azimuth = 2.0 * M_PI * a / kAzimuths;
            const Eigen::Vector3d d(std::cos(elevation) * std::cos(azimuth),
                                    std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
            const double t = cast(origin, d, max_range_m);
            if (t > 0.0) scan.points_sensor.push_back((t * d).cast<float>());
        }
    }
    return scan;
}

// Points of region A's surfaces the first scans saw, each with offsets of -10, 0, +10 cm along
// the surface normal (true SDF -0.1, 0, 0.1 m).
void region_a_queries(std::vector<Eigen::Vector3f>& points, std::vector<float>& sdf_m) {
    const auto add = [&](const Eigen::Vector3d& surface, const Eigen::Vector3d& normal) {
        for (double offset : {-0.1, 0.0, 0.1}) {
            points.push_back((surface + offset * normal).cast<float>());
            sdf_m.push_back(static_cast<float>(offset));
        }
    };
    // Ground beyond the sensors' blind circle (2.4 m at -35 degrees), on the side away from
    // the sphere.
    for (double x = -2.0; x <= 2.0; x += 0.1) {
        for (double y = -4.5; y <= -2.8; y += 0.1) add({x, y, 0.0}, Eigen::Vector3d::UnitZ());
    }
    // The sphere's side facing the sensors (y < centre), above the ground.
    for (double az = M_PI * 1.1; az <= M_PI * 1.9; az += 0.08) {
        for (double el = -0.4; el <= 1.2; el += 0.1) {
            const Eigen::Vector3d n(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                    std::sin(el));
            add(kSphereCentre + kSphereRadiusM * n, n);
        }
    }
}

// Measured (noise-free scans; the default incremental settings but for the scene's ranges, without
// replay): mean |f - sdf| over region A is 1.6-1.8 cm after its scans; at the end 1.62 cm with the
// default regulariser and 2.14 cm without it, the far, oblique views of region B's scans having
// retrained the rows of A's ground.
constexpr double kMaxRegularizedErrorM = 0.018;  // 1.8 cm

struct RunResult {
    double error_after_a_m = 0.0;  ///< mean |f - sdf| over region A after its scans
    double error_end_m = 0.0;      ///< ... after all scans, at the same points
};

RunResult run(float regularization_weight, int replay_frames) {
    MapperConfig config;
    config.octree.leaf_size_m = 0.25;
    // The thresholds below were measured with the paper's smoothstep weights. With the linear
    // default this small scene forgets less without the regulariser (measured: region A's error
    // 0.0128 -> 0.0145 m, +13 %; with it 0.0101 -> 0.0088 m), too little for the 15 % bound.
    config.octree.interpolation = Interpolation::kSmoothstep;
    // ... and with float32 features and the 0.2 m street's lengths, which the scale-free defaults
    // would otherwise stretch to this 0.25 m leaf (mapper_config.hpp).
    config.octree.feature_precision = FeaturePrecision::kFloat32;
    for (const char* key : {"preprocess.voxel_downsample_m", "sampling.normal_radius_m",
                            "training.sigma_m", "incremental.surface_band_m"}) {
        config.mark_set(key);
    }
    config.preprocess.min_range_m = 0.5;
    config.preprocess.max_range_m = 10.0;
    config.trainer.batch_size = 2048;
    config.incremental.importance.regularization_weight = regularization_weight;
    config.incremental.replay_frames = replay_frames;
    IncrementalMapper mapper(config);

    std::vector<Eigen::Vector3f> queries;
    std::vector<float> truth_m;
    region_a_queries(queries, truth_m);
    std::vector<std::uint8_t> evaluated;  // the points inside the map after region A's scans
    const auto error = [&]() {
        std::vector<float> sdf_m;
        std::vector<std::uint8_t> valid;
        mapper.sdf().query(queries, QueryMask::kLevel0, sdf_m, valid);
        if (evaluated.empty()) evaluated = valid;
        double sum = 0.0;
        std::size_t n = 0;
        for (std::size_t i = 0; i < queries.size(); ++i) {
            if (!evaluated[i]) continue;
            EXPECT_TRUE(valid[i]) << "the map only grows";
            sum += std::abs(sdf_m[i] - truth_m[i]);
            ++n;
        }
        EXPECT_GT(n, queries.size() * 9 / 10);
        return sum / static_cast<double>(std::max<std::size_t>(n, 1));
    };

    RunResult result;
    for (double x : {-1.0, -0.5, 0.0, 0.5, 1.0}) mapper.add_scan(make_scan({x, 0.0, 1.7}, 6.0));
    result.error_after_a_m = error();
    for (double x = 4.0; x <= 9.0; x += 0.5) mapper.add_scan(make_scan({x, 0.0, 1.7}, 10.0));
    result.error_end_m = error();
    return result;
}

}  // namespace

TEST(IncrementalForgetting, RegularisationKeepsTheFirstRegionsSdf) {
    // The paper's experiment: each scan trains on its own rays alone (no replay).
    const float lambda = MapperConfig{}.incremental.importance.regularization_weight;
    ASSERT_GT(lambda, 0.0f);
    const RunResult with = run(lambda, 1);
    const RunResult without = run(0.0f, 1);
    std::printf(
        "region A mean SDF error: lambda_r %g: %.4f m -> %.4f m; without: %.4f m -> %.4f m\n",
        lambda, with.error_after_a_m, with.error_end_m, without.error_after_a_m,
        without.error_end_m);
    EXPECT_LT(with.error_end_m, kMaxRegularizedErrorM);
    EXPECT_GT(without.error_end_m, kMaxRegularizedErrorM);
    // Forgetting: without the regulariser region A's error grew by 15 % or more after it was
    // left behind (measured: by 20 %); with it, it stayed (measured: +0 %).
    EXPECT_GT(without.error_end_m, 1.15 * without.error_after_a_m);
    EXPECT_LT(with.error_end_m, 1.1 * with.error_after_a_m);
}

TEST(IncrementalForgetting, ReplayAloneKeepsTheFirstRegionsSdf) {
    // With the default replay (region A's scans replayed while region B is mapped) and no
    // regulariser, region A is not forgotten either: measured 0.0159 -> 0.0132 m, and with the
    // regulariser as well 0.0156 -> 0.0147 m.
    const int replay = MapperConfig{}.incremental.replay_frames;
    ASSERT_GT(replay, 16);  // every scan of this run
    const RunResult replayed = run(0.0f, replay);
    std::printf("region A mean SDF error, replaying %d scans, no regulariser: %.4f m -> %.4f m\n",
                replay, replayed.error_after_a_m, replayed.error_end_m);
    EXPECT_LT(replayed.error_end_m, kMaxRegularizedErrorM);
    EXPECT_LT(replayed.error_end_m, 1.1 * replayed.error_after_a_m);
}
