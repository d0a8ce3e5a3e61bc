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

void ImportanceWeights::resize(std::size_t num_rows) { importance_.resize(num_rows, 0.0f); }

double ImportanceWeights::add_row_gradient(std::int32_t row, const float* param,
                                           const float* anchor, float* grad) const {
    const float omega = importance_[row];
    if (omega == 0.0f) return 0.0;
    // As Eigen arrays so that the row is one SIMD expression; a stack array of at most 64 floats
    // (rows are feature vectors, map.feature_dim <= 64).
    const Eigen::Array<float, Eigen::Dynamic, 1, Eigen::ColMajor, 64, 1> d =
        Eigen::Map<const Eigen::ArrayXf>(param, row_dim_) -
        Eigen::Map<const Eigen::ArrayXf>(anchor, row_dim_);
    Eigen::Map<Eigen::ArrayXf>(grad, row_dim_) +=
        (2.0f * config_.regularization_weight * omega) * d;
    return omega * static_cast<double>(d.square().sum());
}

namespace {
void check_sum(float s, std::size_t row) {
    if (!(s >= 0.0f) || !std::isfinite(s)) {
        throw DataError("importance update: gradient norm sum of row " + std::to_string(row) +
                        " is " + std::to_string(s) + " (must be finite and >= 0)");
    }
}
}  // namespace

void ImportanceWeights::update_importance_rows(const std::vector<std::int32_t>& rows,
                                               const std::vector<float>& sums, float scale) {
    if (rows.size() != sums.size()) {
        throw DataError("importance update: " + std::to_string(sums.size()) + " sums for " +
                        std::to_string(rows.size()) + " rows");
    }
    for (std::size_t i = 0; i < rows.size(); ++i) {
        if (rows[i] < 0 || std::size_t(rows[i]) >= importance_.size()) {
            throw DataError("importance update: row " + std::to_string(rows[i]) +
                            " is outside the table of " + std::to_string(importance_.size()));
        }
        const float s = sums[i] * scale;
        check_sum(s, std::size_t(rows[i]));
        float& omega = importance_[std::size_t(rows[i])];
        omega = std::min(omega + s, config_.importance_cap);
    }
}

void ImportanceWeights::save(BinaryWriter& out) const {
    out.value<std::int32_t>(row_dim_);
    out.array(importance_);
}

void ImportanceWeights::load(BinaryReader& in) {
    const auto row_dim = in.value<std::int32_t>("importance row size");
    if (row_dim != row_dim_) {
        in.fail("importance row size",
                std::to_string(row_dim) + " differs from this map's " + std::to_string(row_dim_));
    }
    importance_ = in.array<float>("importance weights");
}

}  // namespace shine
