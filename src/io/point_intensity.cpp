// Per-point intensity fields: name lookup and the "no intensity" rule.
#include "shine/io/point_intensity.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>

namespace shine {
namespace {

bool equal_without_case(std::string_view a, std::string_view b) {
    return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
               return std::tolower(static_cast<unsigned char>(x)) ==
                      std::tolower(static_cast<unsigned char>(y));
           });
}

}  // namespace

const std::vector<std::string_view>& intensity_field_names() {
    static const std::vector<std::string_view> names = {"intensity", "reflectivity", "reflectance",
                                                        "scalar_intensity", "i"};
    return names;
}

int find_intensity_field(const std::vector<std::string>& field_names) {
    for (const std::string_view name : intensity_field_names()) {
        for (std::size_t i = 0; i < field_names.size(); ++i) {
            if (equal_without_case(field_names[i], name)) return static_cast<int>(i);
        }
    }
    return -1;
}

bool intensity_measured(const std::vector<float>& intensity) {
    return std::any_of(intensity.begin(), intensity.end(),
                       [](float v) { return std::isfinite(v) && v != 0.0f; });
}

void drop_unmeasured_intensity(std::vector<float>& intensity) {
    if (!intensity_measured(intensity)) std::vector<float>().swap(intensity);
}

}  // namespace shine
