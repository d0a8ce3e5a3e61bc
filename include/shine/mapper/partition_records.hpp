// The first half of the training step's reduction (trainer.hpp): one row partition adds the
// gradient records of a chunk's batch to its compact per-row sums. A record is (valid sample b,
// corner k) stored as b * corner_stride + k; its gradient on the corner's feature row is
// coefficient(b, k) / N * h_b (batch_gradient.hpp). Rows are numbered in first-touch order, so
// each row's sum takes its records in the order they come, whatever thread runs the partition.
#pragma once

#include <cstdint>
#include <vector>

#include "shine/model/batch_gradient.hpp"

namespace shine {

/// Adds `records` of `batch` to the partition's sums: a row met for the first time (its
/// local_index entry is negative) gets the next local index, is appended to `rows` and has its
/// dim floats at grads + local * dim zeroed; then each record adds coefficient * inv_n * h of its
/// sample, in record order. `grads` must have room for dim floats per row the records can touch.
/// Dim > 0 fixes the feature size at compile time (no call to zero a row, unrolled sums); the
/// arithmetic is the same as with Dim = 0, which reads it from `dim`.
template <int Dim>
void add_partition_records(const BatchGradient& batch, const std::vector<std::uint32_t>& records,
                           int dim_runtime, float inv_n, std::int32_t* local_index,
                           std::vector<std::int32_t>& rows, float* grads) {
    const int dim = Dim > 0 ? Dim : dim_runtime;
    const std::uint32_t stride = static_cast<std::uint32_t>(batch.corner_stride);
    constexpr std::size_t kAhead = 16;  // local_index is read in random row order
    for (std::size_t r = 0; r < records.size(); ++r) {
        if (r + kAhead < records.size()) {
            __builtin_prefetch(local_index + batch.rows[records[r + kAhead]], 1);
        }
        const std::uint32_t record = records[r];
        const std::int32_t row = batch.rows[record];
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
        const float coefficient = batch.coefficients[record] * inv_n;
        const float* h = batch.h(record / stride);
        for (int l = 0; l < dim; ++l) grad[l] += coefficient * h[l];
    }
}

/// add_partition_records<8> for 8 features (the default), else add_partition_records<0>.
inline void add_partition_records(const BatchGradient& batch,
                                  const std::vector<std::uint32_t>& records, int dim, float inv_n,
                                  std::int32_t* local_index, std::vector<std::int32_t>& rows,
                                  float* grads) {
    if (dim == 8) {
        add_partition_records<8>(batch, records, dim, inv_n, local_index, rows, grads);
    } else {
        add_partition_records<0>(batch, records, dim, inv_n, local_index, rows, grads);
    }
}

}  // namespace shine
