#include "shine/io/run_deskew_record.hpp"

#include <cmath>
#include <nlohmann/json.hpp>

#include "shine/core/error.hpp"

namespace shine {

namespace {

bool positive_finite(double value) { return value > 0.0 && std::isfinite(value); }

SweepTimeModel sweep_from_json(const nlohmann::json& json, const std::string& source) {
    if (!json.is_object()) throw DataError("'" + source + "': deskew.sweep is not an object");
    SweepTimeModel model;
    model.direction =
        parse_sweep_direction(json.at("direction").get<std::string>(), "deskew.sweep.direction");
    model.start_azimuth_deg = json.at("start_azimuth_deg").get<double>();
    model.pose_azimuth_deg = json.at("pose_azimuth_deg").get<double>();
    model.sweep_period_s = json.at("period_s").get<double>();
    if (!std::isfinite(model.start_azimuth_deg) || !std::isfinite(model.pose_azimuth_deg)) {
        throw DataError("'" + source + "': deskew.sweep has an azimuth that is not finite");
    }
    if (!positive_finite(model.sweep_period_s)) {
        throw DataError("'" + source + "': deskew.sweep.period_s is not a positive number");
    }
    return model;
}

RunDeskewRecord record_from_json(const nlohmann::json& stats, const std::string& source) {
    if (!stats.is_object()) throw DataError("'" + source + "' is not a JSON object");
    RunDeskewRecord record;
    const auto deskew = stats.find("deskew");
    if (deskew == stats.end()) return record;
    if (!deskew->is_object()) throw DataError("'" + source + "': deskew is not an object");
    record.active = deskew->value("active", false);
    if (!record.active) return record;
    record.scan_period_s = deskew->value("scan_period_s", record.scan_period_s);
    if (!positive_finite(record.scan_period_s)) {
        throw DataError("'" + source + "': deskew.scan_period_s is not a positive number");
    }
    const auto point_time = deskew->find("point_time");
    const bool azimuth = point_time != deskew->end() && point_time->is_object() &&
                         point_time->value("field", std::string()) == "azimuth";
    const auto sweep = deskew->find("sweep");
    if (azimuth && sweep == deskew->end()) {
        throw DataError("'" + source +
                        "' says the run timed its scans by their azimuth but not how (no "
                        "deskew.sweep: written before it was recorded); map again");
    }
    if (azimuth) record.sweep = sweep_from_json(*sweep, source);
    return record;
}

}  // namespace

std::string sweep_record_json(const SweepTimeModel& model) {
    const nlohmann::json json = {{"direction", to_string(model.direction)},
                                 {"start_azimuth_deg", model.start_azimuth_deg},
                                 {"pose_azimuth_deg", model.pose_azimuth_deg},
                                 {"period_s", model.sweep_period_s}};
    return json.dump();
}

RunDeskewRecord read_run_deskew_record(std::string_view stats_json, const std::string& source) {
    nlohmann::json stats;
    try {
        stats = nlohmann::json::parse(stats_json);
    } catch (const nlohmann::json::exception& e) {
        throw DataError("'" + source + "' is not valid JSON: " + e.what());
    }
    try {
        return record_from_json(stats, source);
    } catch (const nlohmann::json::exception& e) {
        throw DataError("'" + source + "': deskew: " + e.what());
    } catch (const ConfigError& e) {
        throw DataError("'" + source + "': " + e.what());
    }
}

}  // namespace shine
