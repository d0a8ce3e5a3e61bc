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

/// Importance Omega and anchor theta* per row of a growing parameter table of `row_dim` floats.
class ImportanceWeights {
  public:
    ImportanceWeights() = default;
    /// Throws ConfigError for a negative weight or a non-positive cap.
    ImportanceWeights(const ImportanceConfig& config, int row_dim);

    const ImportanceConfig& config() const { return config_; }
    bool enabled() const { return config_.regularization_weight > 0.0f; }
    int row_dim() const { return row_dim_; }
    std::size_t num_rows() const { return importance_.size(); }

    /// Grows to `num_rows` rows; new rows have Omega = 0 (unconstrained) and anchor 0.
    void resize(std::size_t num_rows);

    /// lambda_r * L_r over `rows` for the parameter table `params` (Eq. (3)).
    double value(const float* params, const std::vector<std::int32_t>& rows) const;

    /// Adds d(lambda_r L_r)/dtheta = 2 lambda_r Omega_i (theta_i - theta*_i) to the listed rows of
    /// `grads` and returns lambda_r * L_r over them.
    double add_gradient(const float* params, float* grads,
                        const std::vector<std::int32_t>& rows) const;
    /// As add_gradient(), but the gradient of rows[i] is row_grads[i * row_dim, (i + 1) * row_dim)
    /// (a compact buffer of the listed rows, as the trainer's reduction writes it).
    double add_gradient_listed(const float* params, float* row_grads,
                               const std::vector<std::int32_t>& rows) const;

    /// Eq. (4): Omega_i = min(Omega_i + gradient_norm_sums[i], Omega_m) for every row;
    /// `gradient_norm_sums` has one entry per row (rows beyond it are unchanged). Throws
    /// DataError if it has more entries than there are rows or a negative or non-finite entry.
    void update_importance(const std::vector<float>& gradient_norm_sums);

    /// theta* = theta for every row (after a scan's training has converged).
    void set_anchors(const float* params);

    float importance(std::int32_t row) const { return importance_[row]; }
    const std::vector<float>& importances() const { return importance_; }
    const float* anchor(std::int32_t row) const {
        return anchors_.data() + std::size_t(row) * row_dim_;
    }
    std::size_t memory_bytes() const {
        return (importance_.capacity() + anchors_.capacity()) * sizeof(float);
    }

    /// Omega and theta* of every row (for a checkpoint); load() replaces them, checking that
    /// the stored rows have this table's row_dim.
    void save(BinaryWriter& out) const;
    void load(BinaryReader& in);

  private:
    ImportanceConfig config_;
    int row_dim_ = 1;
    std::vector<float> importance_;  ///< Omega per row
    std::vector<float> anchors_;     ///< theta*, row-major like the parameter table
};

}  // namespace shine
