// libFuzzer target: the deskew record of a mapping run's stats.json (io/run_deskew_record.hpp).
#include <cmath>
#include <cstdlib>

#include "fuzz_common.hpp"
#include "shine/io/run_deskew_record.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    shine_fuzz::expect_value_or_error([&] {
        const shine::RunDeskewRecord record = shine::read_run_deskew_record(
            shine_fuzz::as_view(data, size), shine_fuzz::kSource.string());
        if (record.active && !(record.scan_period_s > 0.0)) std::abort();
        if (record.sweep && !(record.sweep->sweep_period_s > 0.0 &&
                              std::isfinite(record.sweep->start_azimuth_deg))) {
            std::abort();
        }
    });
    return 0;
}
