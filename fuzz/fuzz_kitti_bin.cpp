// libFuzzer target: KITTI .bin scans, then the preprocessing every scan goes through.
#include "fuzz_common.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/point_intensity.hpp"
#include "shine/io/preprocess.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    shine_fuzz::expect_value_or_error([&] {
        std::vector<float> intensity;
        const auto points = shine::parse_kitti_bin(shine_fuzz::as_view(data, size),
                                                   shine_fuzz::kSource, &intensity);
        // One intensity per point, or none (every value 0 or not finite).
        if (!intensity.empty() &&
            (intensity.size() != points.size() || !shine::intensity_measured(intensity))) {
            std::abort();
        }
        // Arbitrary floats (NaN, inf, 1e38, zero range) through the default preprocessing.
        shine::PreprocessStats stats;
        shine::preprocess_scan(points, shine::PreprocessConfig{}, shine_fuzz::kSource, &stats);
        if (stats.input != points.size()) std::abort();
    });
    return 0;
}
