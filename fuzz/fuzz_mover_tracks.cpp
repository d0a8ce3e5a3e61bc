// libFuzzer target: the movers of simulation.json.
#include <cmath>

#include "fuzz_common.hpp"
#include "shine/io/mover_tracks.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    shine_fuzz::expect_value_or_error([&] {
        const shine::MoverTracks tracks =
            shine::parse_mover_tracks(shine_fuzz::as_view(data, size), shine_fuzz::kSource);
        for (const auto& mover : tracks.movers) {
            if (!(mover.size_m.minCoeff() > 0.0) || mover.waypoints.empty()) std::abort();
            const double t = 0.5 * (mover.waypoints.front().time_s + mover.waypoints.back().time_s);
            if (!std::isfinite(t)) continue;
            (void)mover.T_world_body(t);
        }
    });
    return 0;
}
