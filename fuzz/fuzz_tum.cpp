// libFuzzer target: TUM trajectories.
#include "fuzz_common.hpp"
#include "shine/io/tum.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    shine_fuzz::expect_value_or_error([&] {
        const auto poses =
            shine::parse_tum_poses(shine_fuzz::as_view(data, size), shine_fuzz::kSource);
        for (const auto& p : poses) {
            if (!p.T_world_sensor.matrix().allFinite()) std::abort();
        }
    });
    return 0;
}
