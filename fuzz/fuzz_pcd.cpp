// libFuzzer target: PCD point clouds (ascii, binary, binary_compressed), with per-point times
// and intensities.
#include "fuzz_common.hpp"
#include "shine/io/pcd.hpp"
#include "shine/io/point_intensity.hpp"
#include "shine/io/preprocess.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    shine_fuzz::expect_value_or_error([&] {
        const shine::TimedPoints scan =
            shine::parse_pcd_scan(shine_fuzz::as_view(data, size), shine_fuzz::kSource);
        // Scans with per-point times: one time per point, or none.
        if (!scan.point_time_s.empty() && scan.point_time_s.size() != scan.points_sensor.size()) {
            std::abort();
        }
        // Intensities likewise, and an empty list is the only "none".
        if (!scan.intensity.empty() && (scan.intensity.size() != scan.points_sensor.size() ||
                                        !shine::intensity_measured(scan.intensity))) {
            std::abort();
        }
        shine::preprocess_scan(scan.points_sensor, shine::PreprocessConfig{}, shine_fuzz::kSource);
    });
    return 0;
}
