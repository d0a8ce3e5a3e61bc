#include "shine/optim/importance_weights.hpp"

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <string>

#include "shine/core/error.hpp"
#include "shine/io/binary_stream.hpp"

namespace shine {

ImportanceWeights::ImportanceWeights(const ImportanceConfig& config, int row_dim)
    : config_(config), row_dim_(row_dim) {
    if (!(config.regularization_weight >= 0.0f) || !std::isfinite(config.regularization_weight)) {
        throw ConfigError("incremental.regularization_weight must be a finite number >= 0, got " +
                          std::to_string(config.regularization_weight));
    }
    if (!(config.importance_cap > 0.0f)) {
        throw ConfigError("incremental.importance_cap must be positive, got " +
                          std::to_string(config.importance_cap));
    }
    if (row_dim < 1) throw ConfigError("importance weights need a row length of at least 1");
    if (row_dim > 64) throw ConfigError("importance weights support rows of at most 64 floats");
}

void ImportanceWeights::resize(std::size_t num_rows) {
    importance_.resize(num_rows, 0.0f);
    anchors_.resize(num_rows * row_dim_, 0.0f);
}

double ImportanceWeights::value(const float* params, const std::vector<std::int32_t>& rows) const {
    double sum = 0.0;
    for (const std::int32_t row : rows) {
        const float omega = importance_[row];
        if (omega == 0.0f) continue;
        const std::size_t base = std::size_t(row) * row_dim_;
        double squared = 0.0;
        for (int l = 0; l < row_dim_; ++l) {
            const double d = double(params[base + l]) - double(anchors_[base + l]);
            squared += d * d;
        }
        sum += omega * squared;
    }
    return config_.regularization_weight * sum;
}

namespace {
/// 2 lambda Omega (theta - theta*) added to one row's gradient; returns |theta - theta*|^2.
float add_row_gradient(const float* params, const float* anchors, float scale, int dim,
                       float* grad) {
    // As Eigen arrays so that the row is one SIMD expression; a stack array of at most 64 floats
    // (rows are feature vectors, map.feature_dim <= 64).
    const Eigen::Array<float, Eigen::Dynamic, 1, Eigen::ColMajor, 64, 1> d =
        Eigen::Map<const Eigen::ArrayXf>(params, dim) -
        Eigen::Map<const Eigen::ArrayXf>(anchors, dim);
    Eigen::Map<Eigen::ArrayXf>(grad, dim) += scale * d;
    return d.square().sum();
}
}  // namespace

double ImportanceWeights::add_gradient(const float* params, float* grads,
                                       const std::vector<std::int32_t>& rows) const {
    const float lambda = config_.regularization_weight;
    double sum = 0.0;
    for (const std::int32_t row : rows) {
        const float omega = importance_[row];
        if (omega == 0.0f) continue;
        const std::size_t base = std::size_t(row) * row_dim_;
        sum += omega *
               static_cast<double>(add_row_gradient(params + base, anchors_.data() + base,
                                                    2.0f * lambda * omega, row_dim_, grads + base));
    }
    return lambda * sum;
}

double ImportanceWeights::add_gradient_listed(const float* params, float* row_grads,
                                              const std::vector<std::int32_t>& rows) const {
    const float lambda = config_.regularization_weight;
    double sum = 0.0;
    constexpr std::size_t kAhead = 8;  // rows are in random order: prefetch (see RowAdam)
    for (std::size_t i = 0; i < rows.size(); ++i) {
        if (i + kAhead < rows.size()) {
            const std::size_t ahead = std::size_t(rows[i + kAhead]);
            __builtin_prefetch(importance_.data() + ahead);
            __builtin_prefetch(anchors_.data() + ahead * row_dim_);
            __builtin_prefetch(params + ahead * row_dim_);
        }
        const float omega = importance_[rows[i]];
        if (omega == 0.0f) continue;
        const std::size_t base = std::size_t(rows[i]) * row_dim_;
        sum += omega * static_cast<double>(add_row_gradient(params + base, anchors_.data() + base,
                                                            2.0f * lambda * omega, row_dim_,
                                                            row_grads + i * row_dim_));
    }
    return lambda * sum;
}

void ImportanceWeights::update_importance(const std::vector<float>& gradient_norm_sums) {
    if (gradient_norm_sums.size() > importance_.size()) {
        throw DataError("importance update: " + std::to_string(gradient_norm_sums.size()) +
                        " sums for " + std::to_string(importance_.size()) + " rows");
    }
    for (std::size_t i = 0; i < gradient_norm_sums.size(); ++i) {
        const float s = gradient_norm_sums[i];
        if (!(s >= 0.0f) || !std::isfinite(s)) {
            throw DataError("importance update: gradient norm sum of row " + std::to_string(i) +
                            " is " + std::to_string(s) + " (must be finite and >= 0)");
        }
        importance_[i] = std::min(importance_[i] + s, config_.importance_cap);
    }
}

void ImportanceWeights::set_anchors(const float* params) {
    std::copy(params, params + anchors_.size(), anchors_.begin());
}

void ImportanceWeights::save(BinaryWriter& out) const {
    out.value<std::int32_t>(row_dim_);
    out.array(importance_);
    out.array(anchors_);
}

void ImportanceWeights::load(BinaryReader& in) {
    const auto row_dim = in.value<std::int32_t>("importance row size");
    if (row_dim != row_dim_) {
        in.fail("importance row size",
                std::to_string(row_dim) + " differs from this map's " + std::to_string(row_dim_));
    }
    std::vector<float> importance = in.array<float>("importance weights");
    std::vector<float> anchors = in.array<float>("importance anchors");
    if (anchors.size() != importance.size() * static_cast<std::size_t>(row_dim_)) {
        in.fail("importance anchors",
                "do not match the " + std::to_string(importance.size()) + " importance weights");
    }
    importance_ = std::move(importance);
    anchors_ = std::move(anchors);
}

}  // namespace shine
