// Importance weights against catastrophic forgetting in incremental mapping (paper Sec. III,
// "Incremental Mapping Without Forgetting"; the regulariser of Zenke et al. and Aljundi et al.).
//
// Per feature row i of the feature table the map keeps an importance Omega_i and an anchor
// theta*_i, the row's value when the previous scans had converged. Training on the current scan
// adds the regulariser (the paper's Eq. (3), \label{Lr}, weighted by lambda_r in Eq. (5))
//
//     lambda_r * L_r = lambda_r * sum_{i in A} Omega_i * |theta_i - theta*_i|^2
//
// over the rows A that the iteration's samples use, so that rows the earlier scans depended on
// move little. After each scan the importance grows by the scan's sensitivity (Eq. (4),
// \label{importance weight})
//
//     Omega_i = min(Omega*_i + sum_k |dL_bce(x_k, l_k) / dtheta_i|, Omega_m),
//
// the sum running over the samples of that scan (Trainer::accumulate_bce_gradient_norms), and the
// anchors move to the converged values. ShineVDB divides the scan's sum by its sample count N
// before adding it (IncrementalMapper): the data term of the loss is the mean BCE of a batch, so
// lambda_r * Omega then has the data gradient's scale whatever the point density; the paper's
// lambda_r range (1e4-1e6) belongs to its own scaling and does not carry over.
//
// Granularity: one Omega per feature row (a corner's L-vector), not per scalar. The paper writes
// the gradient of parameter i inside a norm, which is a vector norm for a feature vector; and
// every scalar of a row is reached by the same samples with the same weight (a sample's gradient
// on corner c is w_c * dL/df * h, h = df/dF the decoder's input gradient), so per-scalar weights
// would only repeat the frozen decoder's |h_l| pattern in every row while costing L times the
// memory (one float per row here, 1/L of the feature table).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace shine {

/// Strength and cap of the regulariser.
struct ImportanceConfig {
    /// lambda_r; 0 disables the regulariser (and the importance pass). Omega is the mean of the
    /// per-sample gradient norms over a scan's samples (see IncrementalMapper), so lambda_r * Omega
    /// compares directly with the gradient of the batch's mean BCE: values of 1-10 work on the
    /// bundled street, 3 is best there (docs/incremental.md); the paper's 1e4-1e6 belong to its
    /// own loss scaling.
    float regularization_weight = 3.0f;
    /// Omega_m. On the bundled street Omega stays below 0.03 after 50 scans, so the cap only
    /// guards against pathological inputs (a row sampled by almost every sample of every scan).
    float importance_cap = 1.0f;
};

class BinaryReader;
class BinaryWriter;

/// Importance Omega per row of a growing parameter table of `row_dim` floats. The anchors theta*
/// are the rows' values when the current scan began; the trainer keeps them with the rest of a
/// row's optimiser state (feature_row_state.hpp) and hands them in.
class ImportanceWeights {
  public:
    ImportanceWeights() = default;
    /// Throws ConfigError for a negative weight or a non-positive cap.
    ImportanceWeights(const ImportanceConfig& config, int row_dim);

    const ImportanceConfig& config() const { return config_; }
    bool enabled() const { return config_.regularization_weight > 0.0f; }
    int row_dim() const { return row_dim_; }
    std::size_t num_rows() const { return importance_.size(); }

    /// Grows to `num_rows` rows; new rows have Omega = 0 (unconstrained).
    void resize(std::size_t num_rows);

    /// Adds d(Omega_row |theta - theta*|^2)/dtheta = 2 lambda_r Omega_row (theta - theta*) to
    /// `grad` for one row of the set A of Eq. (3) (the row's value, anchor and gradient are
    /// row_dim floats each) and returns Omega_row * |theta - theta*|^2: the caller sums over A and
    /// multiplies by lambda_r.
    double add_row_gradient(std::int32_t row, const float* param, const float* anchor,
                            float* grad) const;

    /// Requests the row's Omega ahead of add_row_gradient() (rows come in random order).
    void prefetch_row(std::int32_t row) const {
        __builtin_prefetch(importance_.data() + static_cast<std::size_t>(row));
    }

    /// Eq. (4) for the rows a scan's importance pass reached: Omega_rows[i] = min(Omega +
    /// sums[i] * scale, Omega_m) (`scale` is 1/N, see IncrementalMapper). Throws DataError for a
    /// row outside the table, a size mismatch, or a negative or non-finite sum.
    void update_importance_rows(const std::vector<std::int32_t>& rows,
                                const std::vector<float>& sums, float scale);

    float importance(std::int32_t row) const { return importance_[row]; }
    const std::vector<float>& importances() const { return importance_; }
    std::size_t memory_bytes() const { return importance_.capacity() * sizeof(float); }

    /// Omega of every row (for a checkpoint); load() replaces them, checking that the stored
    /// table has this one's row_dim.
    void save(BinaryWriter& out) const;
    void load(BinaryReader& in);

  private:
    ImportanceConfig config_;
    int row_dim_ = 1;
    std::vector<float> importance_;  ///< Omega per row
};

}  // namespace shine
