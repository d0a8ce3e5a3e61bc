// libFuzzer target: KITTI calib.txt (the Tr line).
#include "fuzz_common.hpp"
#include "shine/io/kitti.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    shine_fuzz::expect_value_or_error([&] {
        const auto Tr =
            shine::parse_kitti_calib_tr(shine_fuzz::as_view(data, size), shine_fuzz::kSource);
        if (!Tr.matrix().allFinite()) std::abort();
    });
    return 0;
}
