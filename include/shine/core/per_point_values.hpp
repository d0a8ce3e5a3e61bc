// Values that go with the points of a scan one for one (per-point times, ray origins,
// intensities, votes): whoever drops or reorders the points keeps these in step with one of the
// two functions here, so that no filter needs its own copy loop per quantity.
// A vector whose size is not the points' count is a quantity the scan does not have (empty,
// such as the intensity of a scan without one) and is left as it is.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace shine {

/// Keeps, in each of `vectors` that holds one element per flag, the elements whose flag is 0, in
/// order; a vector of another size is left as it is. Returns the number of flags set.
template <class... T>
std::size_t drop_flagged(const std::vector<std::uint8_t>& drop, std::vector<T>&... vectors) {
    const std::size_t n = drop.size();
    const auto compact = [&](auto& values) {
        if (values.size() != n) return;
        std::size_t kept = 0;
        for (std::size_t i = 0; i < n; ++i) {
            if (!drop[i]) values[kept++] = values[i];
        }
        values.resize(kept);
    };
    (compact(vectors), ...);
    return n - static_cast<std::size_t>(std::count(drop.begin(), drop.end(), std::uint8_t{0}));
}

/// values[index[k]] for every k: the values of the points a filter kept, given each kept point's
/// index in the input (preprocess_scan's source_index). A `values` whose size is not
/// `input_count` (a quantity the scan does not have) gives an empty vector.
template <class T>
std::vector<T> gather_per_point(const std::vector<T>& values, std::size_t input_count,
                                const std::vector<std::uint32_t>& index) {
    std::vector<T> out;
    if (values.size() != input_count || values.empty()) return out;
    out.reserve(index.size());
    for (const std::uint32_t i : index) out.push_back(values[i]);
    return out;
}

}  // namespace shine
