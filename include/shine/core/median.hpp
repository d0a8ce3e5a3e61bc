// The median of a list of numbers (the mean of the two middle ones for an even count).
#pragma once

#include <algorithm>
#include <vector>

namespace shine {

/// Median of `values`; 0 for an empty list.
inline double median(std::vector<double> values) {
    if (values.empty()) return 0.0;
    std::sort(values.begin(), values.end());
    const std::size_t n = values.size();
    return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

}  // namespace shine
