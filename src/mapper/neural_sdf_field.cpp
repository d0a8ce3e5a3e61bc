#include "shine/mapper/neural_sdf_field.hpp"

#include "shine/model/sdf_gradient.hpp"

namespace shine {

void NeuralSdfField::evaluate(const std::vector<Eigen::Vector3d>& points_world,
                              std::vector<double>& sdf_m,
                              std::vector<Eigen::Vector3d>& gradient_world,
                              std::vector<std::uint8_t>& valid) const {
    std::vector<Eigen::Vector3f> points_map(points_world.size());
    for (std::size_t i = 0; i < points_world.size(); ++i) {
        points_map[i] = (points_world[i] - sdf_.origin_world_m).cast<float>();
    }
    std::vector<float> sdf_f;
    std::vector<Eigen::Vector3f> gradient_map;
    query_sdf_and_gradient(sdf_, points_map, mask_, sdf_f, gradient_map, valid, &memory_);
    sdf_m.resize(points_world.size());
    gradient_world.resize(points_world.size());
    for (std::size_t i = 0; i < points_world.size(); ++i) {
        sdf_m[i] = sdf_f[i];
        gradient_world[i] = gradient_map[i].cast<double>();
    }
}

}  // namespace shine
