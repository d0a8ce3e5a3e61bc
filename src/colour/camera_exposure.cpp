#include "shine/colour/camera_exposure.hpp"

#include <algorithm>
#include <cmath>
#include <tuple>

#include "shine/core/error.hpp"

namespace shine {

ExposureTrack::ExposureTrack(std::vector<ExposureGain> gains) {
    for (const ExposureGain& g : gains) {
        if (!std::isfinite(g.gain) || !(g.gain > 0.0)) {
            throw DataError("exposure gain of camera '" + g.camera + "' at frame " +
                            std::to_string(g.frame) + " is " + std::to_string(g.gain) +
                            " (a gain is finite and positive)");
        }
    }
    // Stable: of two gains of one frame, the later one given ends last and is kept.
    std::stable_sort(gains.begin(), gains.end(), [](const ExposureGain& a, const ExposureGain& b) {
        return std::tie(a.camera, a.frame) < std::tie(b.camera, b.frame);
    });
    for (ExposureGain& g : gains) {
        if (!gains_.empty() && gains_.back().camera == g.camera && gains_.back().frame == g.frame) {
            gains_.back() = std::move(g);
        } else {
            gains_.push_back(std::move(g));
        }
    }
}

double ExposureTrack::gain_at(const std::string& camera, std::size_t frame) const {
    const auto first = std::lower_bound(
        gains_.begin(), gains_.end(), camera,
        [](const ExposureGain& g, const std::string& name) { return g.camera < name; });
    auto last = first;
    while (last != gains_.end() && last->camera == camera) ++last;
    if (first == last) return 1.0;
    const auto after = std::lower_bound(
        first, last, frame, [](const ExposureGain& g, std::size_t f) { return g.frame < f; });
    if (after == last) return std::prev(last)->gain;
    if (after->frame == frame || after == first) return after->gain;
    const ExposureGain& before = *std::prev(after);
    const double s = static_cast<double>(frame - before.frame) /
                     static_cast<double>(after->frame - before.frame);
    return std::exp((1.0 - s) * std::log(before.gain) + s * std::log(after->gain));
}

}  // namespace shine
