// add_partition_records (the training step's per-partition gradient sums) against a plain
// reference: rows in first-touch order and each row's sum taken record by record, bit for bit,
// with the feature size fixed at compile time and read at run time.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <random>
#include <vector>

#include "shine/mapper/partition_records.hpp"

using namespace shine;

namespace {

/// A batch of `samples` valid samples with 3 levels (24 corners each, some samples with fewer),
/// corner rows drawn from [0, num_rows) with many repeats, random coefficients and h.
BatchGradient random_batch(int samples, int dim, int num_rows, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> row(0, num_rows - 1);
    std::uniform_real_distribution<float> value(-2.0f, 2.0f);
    BatchGradient batch;
    batch.corner_stride = 24;
    batch.decoder.input_gradient.resize(dim, samples);
    for (int b = 0; b < samples; ++b) {
        batch.sample.push_back(static_cast<std::uint32_t>(b));
        batch.corners.push_back(static_cast<std::uint8_t>(b % 5 == 0 ? 16 : 24));
        for (int k = 0; k < batch.corner_stride; ++k) {
            batch.rows.push_back(row(rng));
            batch.coefficients.push_back(value(rng));
        }
        for (int l = 0; l < dim; ++l) batch.decoder.input_gradient(l, b) = value(rng);
    }
    return batch;
}

/// The records of the batch's corners whose rows are odd (one of two "partitions"), in sample and
/// corner order, as the trainer sorts them: the corner's row and coefficient and the sample.
std::vector<PartitionRecord> odd_row_records(const BatchGradient& batch) {
    std::vector<PartitionRecord> records;
    for (std::size_t b = 0; b < batch.num_valid(); ++b) {
        for (int k = 0; k < batch.corners[b]; ++k) {
            const std::size_t slot = b * batch.corner_stride + k;
            if (batch.rows[slot] % 2 == 1) {
                records.push_back(
                    {batch.rows[slot], batch.coefficients[slot], static_cast<std::uint32_t>(b)});
            }
        }
    }
    return records;
}

struct Sums {
    std::vector<std::int32_t> rows;
    std::vector<float> grads;
};

/// The plain reference: a map from row to its position, each record's contribution added in
/// order, every term computed as coefficient * inv_n, then times h.
Sums reference_sums(const std::vector<const BatchGradient*>& batches,
                    const std::vector<std::vector<PartitionRecord>>& records, int dim,
                    float inv_n) {
    Sums sums;
    std::map<std::int32_t, std::size_t> position;
    for (std::size_t c = 0; c < batches.size(); ++c) {
        const BatchGradient& batch = *batches[c];
        for (const PartitionRecord& record : records[c]) {
            auto [it, fresh] = position.emplace(record.row, sums.rows.size());
            if (fresh) {
                sums.rows.push_back(record.row);
                sums.grads.resize(sums.grads.size() + dim, 0.0f);
            }
            const float coefficient = record.coefficient * inv_n;
            for (int l = 0; l < dim; ++l) {
                sums.grads[it->second * dim + l] +=
                    coefficient * batch.decoder.input_gradient(l, Eigen::Index(record.sample));
            }
        }
    }
    return sums;
}

/// Runs `add` over the batches in order with a fresh local index, as one partition of a step.
template <typename Add>
Sums partition_sums(const std::vector<const BatchGradient*>& batches,
                    const std::vector<std::vector<PartitionRecord>>& records, int dim, int num_rows,
                    Add add) {
    std::vector<std::int32_t> local_index(num_rows, -1);
    std::size_t total = 0;
    for (const auto& r : records) total += r.size();
    Sums sums;
    std::vector<float> grads(total * dim, 7.0f);  // not zero: each new row must be cleared
    for (std::size_t c = 0; c < batches.size(); ++c) {
        add(*batches[c], records[c], local_index.data(), sums.rows, grads.data());
    }
    sums.grads.assign(grads.begin(), grads.begin() + sums.rows.size() * dim);
    for (std::size_t i = 0; i < sums.rows.size(); ++i) {
        EXPECT_EQ(local_index[sums.rows[i]], static_cast<std::int32_t>(i));
    }
    return sums;
}

}  // namespace

TEST(PartitionRecords, EqualThePlainReferenceBitForBit) {
    constexpr int kRows = 300;  // few rows: most are met many times
    const float inv_n = 1.0f / 3000.0f;
    for (const int dim : {8, 5, 1}) {
        const BatchGradient first = random_batch(120, dim, kRows, 1u + dim);
        const BatchGradient second = random_batch(90, dim, kRows, 100u + dim);
        const std::vector<const BatchGradient*> batches = {&first, &second};
        const std::vector<std::vector<PartitionRecord>> records = {odd_row_records(first),
                                                                   odd_row_records(second)};
        ASSERT_GT(records[0].size(), 500u);
        const Sums expected = reference_sums(batches, records, dim, inv_n);
        const Sums dispatched =
            partition_sums(batches, records, dim, kRows,
                           [&](const BatchGradient& b, const std::vector<PartitionRecord>& r,
                               std::int32_t* local, std::vector<std::int32_t>& rows, float* grads) {
                               add_partition_records(b, r, dim, inv_n, local, rows, grads);
                           });
        const Sums runtime_dim =
            partition_sums(batches, records, dim, kRows,
                           [&](const BatchGradient& b, const std::vector<PartitionRecord>& r,
                               std::int32_t* local, std::vector<std::int32_t>& rows, float* grads) {
                               add_partition_records<0>(b, r, dim, inv_n, local, rows, grads);
                           });
        EXPECT_EQ(dispatched.rows, expected.rows) << "dim " << dim;
        EXPECT_EQ(dispatched.grads, expected.grads) << "dim " << dim;
        EXPECT_EQ(runtime_dim.rows, expected.rows) << "dim " << dim;
        EXPECT_EQ(runtime_dim.grads, expected.grads) << "dim " << dim;
        // Only odd rows, each once, and sums that are not all zero.
        for (const std::int32_t row : expected.rows) EXPECT_EQ(row % 2, 1);
        EXPECT_GT(expected.rows.size(), 100u);
        float largest = 0.0f;
        for (const float g : expected.grads) largest = std::max(largest, std::abs(g));
        EXPECT_GT(largest, 1e-4f);
    }
}
