// The feature table of the map: one row of feature_dim values per allocated node corner, stored
// contiguously in float32 or, to halve the map, in float16 (Imath::half, OpenVDB's own half type).
//
// The encoding kernels read the table through a FeatureTableView in whatever precision it is
// stored in and compute in float; the optimiser updates float32 values (a float16 map is trained
// through a float32 master copy, see Trainer).
#pragma once

#include <Imath/half.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "shine/core/trivial_array.hpp"

namespace shine {

/// Storage precision of the feature table.
enum class FeaturePrecision : std::uint8_t {
    kFloat32,  ///< 4 bytes per feature
    kFloat16,  ///< 2 bytes per feature (IEEE half, 11-bit significand)
};

/// "float32" or "float16" (the YAML and file spelling).
const char* to_string(FeaturePrecision precision);
/// Parses "float32" / "float16"; throws ConfigError naming `key` otherwise.
FeaturePrecision parse_feature_precision(const std::string& text, const std::string& key);

/// Read-only pointer to a feature table in its storage precision: exactly one of f32 / f16 is
/// set (neither for an empty table).
struct FeatureTableView {
    const float* f32 = nullptr;
    const Imath::half* f16 = nullptr;
};

/// Rows of `dim` features in one precision.
class FeatureTable {
  public:
    explicit FeatureTable(int dim = 8, FeaturePrecision precision = FeaturePrecision::kFloat32);

    FeaturePrecision precision() const { return precision_; }
    int dim() const { return dim_; }
    std::size_t num_rows() const { return size() / static_cast<std::size_t>(dim_); }
    /// Number of features (num_rows() * dim()).
    std::size_t size() const {
        return precision_ == FeaturePrecision::kFloat32 ? f32_.size() : f16_.size();
    }
    /// Bytes of storage held (the table is sized exactly).
    std::size_t bytes() const { return f32_.bytes() + f16_.bytes(); }

    /// Resizes to exactly `num_rows` rows; new rows are zero. Growing does not copy the table
    /// (TrivialArray), so a scan's new rows cost what they hold, not the map's size.
    void resize(std::size_t num_rows);
    /// Converts every feature to `precision` (float32 -> float16 rounds to nearest even).
    void set_precision(FeaturePrecision precision);

    /// The storage, for the encoding kernels.
    FeatureTableView data() const;
    /// float32 storage; throws Error for a float16 table (train through a float32 copy).
    float* floats();
    const float* floats() const;
    /// float16 storage; throws Error for a float32 table.
    Imath::half* halves();
    const Imath::half* halves() const;
    /// Feature `i` of a float32 table (throws for float16, as floats()).
    float& operator[](std::size_t i) { return floats()[i]; }
    /// Feature `i`, in float, whatever the precision.
    float operator[](std::size_t i) const {
        return precision_ == FeaturePrecision::kFloat32 ? f32_[i] : static_cast<float>(f16_[i]);
    }

    /// Row `row` converted to float (dim() values).
    void get_row(std::size_t row, float* out) const;
    /// Stores dim() floats into row `row`, rounding them to the table's precision.
    void set_row(std::size_t row, const float* values);
    /// Copies `count` rows from `src` (same precision and dim) without conversion.
    void copy_rows(const FeatureTable& src, std::size_t src_row, std::size_t dst_row,
                   std::size_t count);
    /// Every feature in float, row-major.
    std::vector<float> to_floats() const;

  private:
    int dim_;
    FeaturePrecision precision_;
    TrivialArray<float> f32_;
    TrivialArray<Imath::half> f16_;
};

}  // namespace shine
