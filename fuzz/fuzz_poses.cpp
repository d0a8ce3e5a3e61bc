// libFuzzer target: KITTI poses.txt.
#include "fuzz_common.hpp"
#include "shine/io/kitti.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    shine_fuzz::expect_value_or_error([&] {
        const auto poses =
            shine::parse_kitti_poses(shine_fuzz::as_view(data, size), shine_fuzz::kSource);
        for (const auto& T : poses) {
            if (!T.matrix().allFinite()) std::abort();  // the reader promises finite poses
        }
    });
    return 0;
}
