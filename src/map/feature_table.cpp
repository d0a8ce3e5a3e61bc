#include "shine/map/feature_table.hpp"

#include <algorithm>
#include <cstring>

#include "shine/core/error.hpp"
#include "shine/map/half_convert.hpp"

namespace shine {

const char* to_string(FeaturePrecision precision) {
    return precision == FeaturePrecision::kFloat16 ? "float16" : "float32";
}

FeaturePrecision parse_feature_precision(const std::string& text, const std::string& key) {
    if (text == "float32") return FeaturePrecision::kFloat32;
    if (text == "float16") return FeaturePrecision::kFloat16;
    throw ConfigError("key '" + key + "': expected 'float32' or 'float16', got '" + text + "'");
}

FeatureTable::FeatureTable(int dim, FeaturePrecision precision) : dim_(dim), precision_(precision) {
    if (dim < 1) throw ConfigError("feature_dim must be positive, got " + std::to_string(dim));
}

void FeatureTable::resize(std::size_t num_rows) {
    // Sized exactly (not grown geometrically) so that bytes() is the table's real size.
    const std::size_t n = num_rows * static_cast<std::size_t>(dim_);
    if (precision_ == FeaturePrecision::kFloat32) {
        f32_.resize(n, 0.0f);
    } else {
        f16_.resize(n, Imath::half(0.0f));
    }
}

void FeatureTable::set_precision(FeaturePrecision precision) {
    if (precision == precision_) return;
    if (precision == FeaturePrecision::kFloat16) {
        f16_ = TrivialArray<Imath::half>(f32_.begin(), f32_.end());
        f32_ = TrivialArray<float>();
    } else {
        f32_ = TrivialArray<float>(f16_.begin(), f16_.end());
        f16_ = TrivialArray<Imath::half>();
    }
    precision_ = precision;
}

FeatureTableView FeatureTable::data() const {
    FeatureTableView view;
    if (precision_ == FeaturePrecision::kFloat32) {
        view.f32 = f32_.data();
    } else {
        view.f16 = f16_.data();
    }
    return view;
}

float* FeatureTable::floats() {
    if (precision_ != FeaturePrecision::kFloat32) {
        throw Error(
            "the feature table is stored in float16; read it with get_row() or convert it "
            "with set_precision(float32) before writing floats");
    }
    return f32_.data();
}

const float* FeatureTable::floats() const { return const_cast<FeatureTable*>(this)->floats(); }

Imath::half* FeatureTable::halves() {
    if (precision_ != FeaturePrecision::kFloat16) {
        throw Error("the feature table is stored in float32, not float16");
    }
    return f16_.data();
}

const Imath::half* FeatureTable::halves() const {
    return const_cast<FeatureTable*>(this)->halves();
}

void FeatureTable::get_row(std::size_t row, float* out) const {
    const std::size_t base = row * static_cast<std::size_t>(dim_);
    if (precision_ == FeaturePrecision::kFloat32) {
        std::copy_n(f32_.data() + base, dim_, out);
    } else {
        halves_to_floats(f16_.data() + base, out, std::size_t(dim_));
    }
}

void FeatureTable::set_row(std::size_t row, const float* values) {
    const std::size_t base = row * static_cast<std::size_t>(dim_);
    if (precision_ == FeaturePrecision::kFloat32) {
        std::copy_n(values, dim_, f32_.data() + base);
    } else {
        floats_to_halves(values, f16_.data() + base, std::size_t(dim_));
    }
}

void FeatureTable::copy_rows(const FeatureTable& src, std::size_t src_row, std::size_t dst_row,
                             std::size_t count) {
    if (src.precision_ != precision_ || src.dim_ != dim_) {
        throw Error("copy_rows: feature tables differ in precision or dimension");
    }
    const std::size_t d = static_cast<std::size_t>(dim_);
    if (count == 0) return;
    if (precision_ == FeaturePrecision::kFloat32) {
        std::memcpy(f32_.data() + dst_row * d, src.f32_.data() + src_row * d,
                    count * d * sizeof(float));
    } else {
        std::memcpy(f16_.data() + dst_row * d, src.f16_.data() + src_row * d,
                    count * d * sizeof(Imath::half));
    }
}

std::vector<float> FeatureTable::to_floats() const {
    if (precision_ == FeaturePrecision::kFloat32)
        return std::vector<float>(f32_.begin(), f32_.end());
    return std::vector<float>(f16_.begin(), f16_.end());
}

}  // namespace shine
