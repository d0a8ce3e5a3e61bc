// The neural map as the odometry's SdfField: values are NeuralSdf::query's at the map-frame point,
// and the gradient agrees with central differences of the field in WORLD coordinates, on a map
// whose origin is UTM-far from the world's (so that a frame mix-up cannot pass).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "shine/mapper/neural_sdf_field.hpp"
#include "shine/model/neural_sdf.hpp"

using namespace shine;

namespace {

constexpr double kStepM = 1e-3;   // central-difference step: 1 mm in 0.25 m cells
constexpr double kAbsTol = 2e-3;  // per metre: float rounding of values ~0.1 over 2 mm
constexpr double kRelTol = 2e-2;  // truncation and the odd ReLU kink within the step

const Eigen::Vector3d kOriginWorldM(512000.0, 5403000.0, 100.0);

NeuralSdf random_map() {
    FeatureOctreeConfig octree;
    octree.leaf_size_m = 0.25;
    octree.num_levels = 2;
    octree.init_std = 0.3f;
    NeuralSdf sdf(octree, DecoderConfig{8, {16, 16}, 5});
    std::vector<Eigen::Vector3f> seeds;
    for (float x = 0.05f; x < 1.0f; x += 0.2f) {
        for (float y = 0.05f; y < 1.0f; y += 0.2f) seeds.emplace_back(x, y, 0.1f);
    }
    sdf.octree.allocate_cells(seeds);
    sdf.origin_world_m = kOriginWorldM;
    return sdf;
}

std::vector<Eigen::Vector3f> random_map_points(int count) {
    std::mt19937 rng(21);
    std::uniform_real_distribution<float> u(0.06f, 0.94f);
    std::uniform_real_distribution<float> uz(0.02f, 0.22f);
    std::vector<Eigen::Vector3f> points;
    for (int i = 0; i < count; ++i) points.emplace_back(u(rng), u(rng), uz(rng));
    return points;
}

}  // namespace

TEST(NeuralSdfField, ValuesAreTheMapsAtTheMapFramePoint) {
    const NeuralSdf sdf = random_map();
    const std::vector<Eigen::Vector3f> points_map = random_map_points(100);
    std::vector<Eigen::Vector3d> points_world;
    for (const auto& p : points_map) points_world.push_back(kOriginWorldM + p.cast<double>());

    std::vector<double> value;
    std::vector<Eigen::Vector3d> gradient;
    std::vector<std::uint8_t> valid;
    NeuralSdfField(sdf).evaluate(points_world, value, gradient, valid);
    std::vector<float> reference;
    std::vector<std::uint8_t> reference_valid;
    sdf.query(points_map, QueryMask::kLevel0, reference, reference_valid);
    ASSERT_EQ(value.size(), points_map.size());
    EXPECT_EQ(valid, reference_valid);
    int inside = 0;
    for (std::size_t i = 0; i < value.size(); ++i) {
        EXPECT_EQ(value[i], static_cast<double>(reference[i])) << "point " << i;
        inside += valid[i];
    }
    EXPECT_GE(inside, 80);

    // The same points taken as world coordinates lie 5400 km away, outside the map.
    std::vector<Eigen::Vector3d> wrong_frame;
    for (const auto& p : points_map) wrong_frame.push_back(p.cast<double>());
    NeuralSdfField(sdf).evaluate(wrong_frame, value, gradient, valid);
    for (std::size_t i = 0; i < valid.size(); ++i) EXPECT_EQ(valid[i], 0) << "point " << i;
}

TEST(NeuralSdfField, GradientMatchesCentralDifferencesInWorldCoordinates) {
    const NeuralSdf sdf = random_map();
    const NeuralSdfField field(sdf);
    std::vector<Eigen::Vector3d> points_world;
    for (const auto& p : random_map_points(200)) {
        points_world.push_back(kOriginWorldM + p.cast<double>());
    }
    std::vector<double> value;
    std::vector<Eigen::Vector3d> gradient;
    std::vector<std::uint8_t> valid;
    field.evaluate(points_world, value, gradient, valid);

    std::vector<Eigen::Vector3d> shifted;
    for (const auto& p : points_world) {
        for (int a = 0; a < 3; ++a) {
            shifted.push_back(p + kStepM * Eigen::Vector3d::Unit(a));
            shifted.push_back(p - kStepM * Eigen::Vector3d::Unit(a));
        }
    }
    std::vector<double> shifted_value;
    std::vector<Eigen::Vector3d> shifted_gradient;
    std::vector<std::uint8_t> shifted_valid;
    field.evaluate(shifted, shifted_value, shifted_gradient, shifted_valid);
    // As in test_model_sdf_gradient.cpp: where a ReLU kink lies within the step the analytic
    // derivative is one of the one-sided differences; kinks must stay the exception.
    const auto close = [](double analytic, double numeric) {
        return std::abs(analytic - numeric) <= kAbsTol + kRelTol * std::abs(numeric);
    };
    int checked = 0, central = 0;
    double gradient_norm_sum = 0.0;
    for (std::size_t i = 0; i < points_world.size(); ++i) {
        if (!valid[i]) continue;
        gradient_norm_sum += gradient[i].norm();
        for (int a = 0; a < 3; ++a) {
            const std::size_t k = 6 * i + 2 * std::size_t(a);
            if (!shifted_valid[k] || !shifted_valid[k + 1]) continue;
            const double plus = shifted_value[k], minus = shifted_value[k + 1], at = value[i];
            const double numeric = (plus - minus) / (2.0 * kStepM);
            ++checked;
            if (close(gradient[i][a], numeric)) {
                ++central;
            } else {
                EXPECT_TRUE(close(gradient[i][a], (plus - at) / kStepM) ||
                            close(gradient[i][a], (at - minus) / kStepM))
                    << "point " << i << " axis " << a << ": analytic " << gradient[i][a]
                    << ", central " << numeric;
            }
        }
    }
    EXPECT_GE(checked, 500);
    EXPECT_GE(central, checked * 9 / 10);
    EXPECT_GT(gradient_norm_sum / checked * 3, 0.05);  // a random map has real slopes
}
