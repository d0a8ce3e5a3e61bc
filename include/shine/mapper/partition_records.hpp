// The first half of the training step's reduction (trainer.hpp): one row partition adds the
// gradient records of a chunk's batch to its compact per-row sums. A record is a valid sample b's
// corner k: its gradient on the corner's feature row is coefficient(b, k) / N * h_b
// (batch_gradient.hpp). Rows are numbered in first-touch order, so each row's sum takes its
// records in the order they come, whatever thread runs the partition.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "shine/model/batch_gradient.hpp"

namespace shine {

/// One record of a row partition: the corner's feature row, its coefficient(b, k) and the valid
/// sample b, copied out of the batch when the records are sorted into partitions (the batch is
/// then in cache), so that a partition reads its records in one pass instead of looking each one
/// up in the batch at random.
struct PartitionRecord {
    std::int32_t row = 0;
    float coefficient = 0.0f;
    std::uint32_t sample = 0;
};

/// Adds `records` (of `batch`: h_b is read from it) to the partition's sums: a row met for the
/// first time (its local_index entry is negative) gets the next local index, is appended to
/// `rows` and has its dim floats at grads + local * dim zeroed; then each record adds
/// coefficient * inv_n * h of its sample, in record order. `grads` must have room for dim floats
/// per row the records can touch. Dim > 0 fixes the feature size at compile time (no call to zero
/// a row, the sums in vector registers); the arithmetic is the same as with Dim = 0, which reads
/// it from `dim`.
template <int Dim>
void add_partition_records(const BatchGradient& batch, const std::vector<PartitionRecord>& records,
                           int dim_runtime, float inv_n, std::int32_t* local_index,
                           std::vector<std::int32_t>& rows, float* grads) {
    const int dim = Dim > 0 ? Dim : dim_runtime;
    constexpr std::size_t kAhead = 16;  // local_index is read in random row order
    const PartitionRecord* record = records.data();
    const std::size_t n = records.size();
    for (std::size_t r = 0; r < n; ++r) {
        if (r + kAhead < n) __builtin_prefetch(local_index + record[r + kAhead].row, 1);
        const std::int32_t row = record[r].row;
        std::int32_t& local = local_index[row];
        float* grad;
        if (local < 0) {
            local = static_cast<std::int32_t>(rows.size());
            rows.push_back(row);
            grad = grads + std::size_t(local) * dim;
            for (int l = 0; l < dim; ++l) grad[l] = 0.0f;
        } else {
            grad = grads + std::size_t(local) * dim;
        }
        const float coefficient = record[r].coefficient * inv_n;
        const float* h = batch.h(record[r].sample);
        if constexpr (Dim > 0) {
            // grad[l] + coefficient * h[l] in every element, as the loop below.
            using Row = Eigen::Array<float, Dim, 1>;
            Eigen::Map<Row>(grad) += coefficient * Eigen::Map<const Row>(h);
        } else {
            for (int l = 0; l < dim; ++l) grad[l] += coefficient * h[l];
        }
    }
}

/// add_partition_records<8> for 8 features (the default), else add_partition_records<0>.
inline void add_partition_records(const BatchGradient& batch,
                                  const std::vector<PartitionRecord>& records, int dim, float inv_n,
                                  std::int32_t* local_index, std::vector<std::int32_t>& rows,
                                  float* grads) {
    if (dim == 8) {
        add_partition_records<8>(batch, records, dim, inv_n, local_index, rows, grads);
    } else {
        add_partition_records<0>(batch, records, dim, inv_n, local_index, rows, grads);
    }
}

}  // namespace shine
