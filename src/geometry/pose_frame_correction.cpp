#include "shine/geometry/pose_frame_correction.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "shine/core/error.hpp"

namespace shine {

PoseFrameCorrection::PoseFrameCorrection(std::vector<Eigen::Isometry3d> given,
                                         std::vector<Eigen::Isometry3d> refined, double sigma_m)
    : given_(std::move(given)), refined_(std::move(refined)), sigma_m_(sigma_m) {
    if (given_.size() != refined_.size()) {
        throw DataError("pose frame correction: " + std::to_string(given_.size()) +
                        " given poses for " + std::to_string(refined_.size()) + " refined ones");
    }
    if (given_.empty()) throw DataError("pose frame correction: no scan");
    if (!(sigma_m_ > 0.0)) throw ConfigError("pose frame correction: sigma_m must be positive");
    map_to_given_.reserve(given_.size());
    given_to_map_.reserve(given_.size());
    for (std::size_t k = 0; k < given_.size(); ++k) {
        map_to_given_.push_back(given_[k] * refined_[k].inverse());
        given_to_map_.push_back(map_to_given_.back().inverse());
    }
}

Eigen::Isometry3d PoseFrameCorrection::to_given(const Eigen::Isometry3d& T_map_frame) const {
    return blend(T_map_frame, refined_, map_to_given_);
}

Eigen::Isometry3d PoseFrameCorrection::to_map(const Eigen::Isometry3d& T_given_frame) const {
    return blend(T_given_frame, given_, given_to_map_);
}

Eigen::Isometry3d PoseFrameCorrection::blend(const Eigen::Isometry3d& T,
                                             const std::vector<Eigen::Isometry3d>& anchors,
                                             const std::vector<Eigen::Isometry3d>& from_to) const {
    const Eigen::Vector3d p = T.translation();
    std::vector<double> d2(anchors.size());
    double nearest = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < anchors.size(); ++k) {
        d2[k] = (anchors[k].translation() - p).squaredNorm();
        nearest = std::min(nearest, d2[k]);
    }
    const double inv_two_sigma2 = 1.0 / (2.0 * sigma_m_ * sigma_m_);
    const Eigen::Quaterniond q_first(from_to.front().linear());
    Eigen::Vector3d displacement = Eigen::Vector3d::Zero();
    Eigen::Vector4d q_sum = Eigen::Vector4d::Zero();
    double weight_sum = 0.0;
    for (std::size_t k = 0; k < anchors.size(); ++k) {
        const double w = std::exp(-(d2[k] - nearest) * inv_two_sigma2);
        if (w < 1e-12) continue;
        displacement += w * (from_to[k] * p - p);
        Eigen::Quaterniond q(from_to[k].linear());
        if (q.coeffs().dot(q_first.coeffs()) < 0.0) q.coeffs() = -q.coeffs();
        q_sum += w * q.coeffs();
        weight_sum += w;
    }
    // The nearest scan has weight 1, so weight_sum >= 1.
    Eigen::Quaterniond q_mean;
    q_mean.coeffs() = q_sum / weight_sum;
    q_mean.normalize();
    Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
    out.linear() = q_mean.toRotationMatrix() * T.linear();
    out.translation() = p + displacement / weight_sum;
    return out;
}

}  // namespace shine
