// libFuzzer target: PCD point clouds (ascii, binary, binary_compressed).
#include "fuzz_common.hpp"
#include "shine/io/pcd.hpp"
#include "shine/io/preprocess.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    shine_fuzz::expect_value_or_error([&] {
        const auto points =
            shine::parse_pcd_points(shine_fuzz::as_view(data, size), shine_fuzz::kSource);
        shine::preprocess_scan(points, shine::PreprocessConfig{}, shine_fuzz::kSource);
    });
    return 0;
}
