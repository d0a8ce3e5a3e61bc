#include "shine/colour/exposure_record.hpp"

#include <cmath>
#include <nlohmann/json.hpp>
#include <vector>

#include "shine/core/error.hpp"

namespace shine {

std::string exposure_record_json(const ExposureTrack& track) {
    nlohmann::json gains = nlohmann::json::array();
    for (const ExposureGain& g : track.gains()) {
        gains.push_back({{"camera", g.camera}, {"frame", g.frame}, {"gain", g.gain}});
    }
    return gains.dump();
}

ExposureTrack read_exposure_record(std::string_view stats_json, const std::string& source) {
    nlohmann::json stats;
    try {
        stats = nlohmann::json::parse(stats_json);
    } catch (const nlohmann::json::exception& e) {
        throw DataError("'" + source + "' is not JSON: " + e.what());
    }
    if (!stats.is_object()) throw DataError("'" + source + "' is not a JSON object");
    const auto appearance = stats.find("appearance");
    if (appearance == stats.end()) return {};
    if (!appearance->is_object()) throw DataError("'" + source + "': appearance is not an object");
    const auto exposure = appearance->find("exposure");
    if (exposure == appearance->end()) return {};
    if (!exposure->is_array()) {
        throw DataError("'" + source + "': appearance.exposure is not an array");
    }
    std::vector<ExposureGain> gains;
    for (std::size_t k = 0; k < exposure->size(); ++k) {
        const nlohmann::json& g = (*exposure)[k];
        const std::string where =
            "'" + source + "': appearance.exposure[" + std::to_string(k) + "]";
        if (!g.is_object()) throw DataError(where + " is not an object");
        const auto camera = g.find("camera");
        const auto frame = g.find("frame");
        const auto gain = g.find("gain");
        if (camera == g.end() || !camera->is_string() || frame == g.end() ||
            !frame->is_number_unsigned() || gain == g.end() || !gain->is_number()) {
            throw DataError(where +
                            " needs a camera name (text), a frame (a whole number from 0) and a "
                            "gain (a number)");
        }
        const double value = gain->get<double>();
        if (!std::isfinite(value) || !(value > 0.0)) {
            throw DataError(where + ": the gain " + std::to_string(value) +
                            " is not a finite positive number");
        }
        gains.push_back({camera->get<std::string>(), frame->get<std::size_t>(), value});
    }
    return ExposureTrack(std::move(gains));
}

}  // namespace shine
