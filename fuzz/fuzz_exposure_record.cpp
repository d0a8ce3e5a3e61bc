// libFuzzer target: the exposure gains of a mapping run's stats.json (colour/exposure_record.hpp).
#include <cmath>
#include <cstdlib>

#include "fuzz_common.hpp"
#include "shine/colour/exposure_record.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    shine_fuzz::expect_value_or_error([&] {
        const shine::ExposureTrack track = shine::read_exposure_record(
            shine_fuzz::as_view(data, size), shine_fuzz::kSource.string());
        for (const shine::ExposureGain& g : track.gains()) {
            const double at = track.gain_at(g.camera, g.frame + 1);
            if (!(g.gain > 0.0) || !std::isfinite(g.gain) || !(at > 0.0) || !std::isfinite(at)) {
                std::abort();
            }
        }
    });
    return 0;
}
