#include "shine/eval/heldout_ranges.hpp"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>

#include "shine/core/error.hpp"

namespace shine {
namespace {

constexpr std::size_t kRaysPerBlock = 4096;

/// The median of `values` (reordered); 0 for none.
double median_of(std::vector<float>& values) {
    if (values.empty()) return 0.0;
    const std::size_t mid = values.size() / 2;
    std::nth_element(values.begin(), values.begin() + mid, values.end());
    const double upper = values[mid];
    if (values.size() % 2 == 1) return upper;
    const double lower = *std::max_element(values.begin(), values.begin() + mid);
    return 0.5 * (lower + upper);
}

/// Fills the error figures of `stats` from the hits' errors (in a fixed order).
void summarise(std::vector<float>& abs_errors_m, RangeErrorStats& stats) {
    double sum = 0.0;
    for (const float e : abs_errors_m) sum += e;
    stats.mean_abs_error_m = abs_errors_m.empty() ? 0.0 : sum / double(abs_errors_m.size());
    stats.median_abs_error_m = median_of(abs_errors_m);
}

void check_config(const HeldoutConfig& config) {
    if (!(config.threshold_m > 0.0)) throw ConfigError("held-out threshold_m must be positive");
    if (!(config.min_range_m >= 0.0) || !(config.max_range_m > config.min_range_m)) {
        throw ConfigError("held-out ranges need 0 <= min_range_m < max_range_m");
    }
    if (!(config.overshoot_m >= 0.0)) throw ConfigError("held-out overshoot_m must be >= 0");
}

nlohmann::json stats_json(const RangeErrorStats& s) {
    return {{"rays", s.rays},
            {"hits", s.hits},
            {"within", s.within},
            {"hit_ratio", s.hit_ratio()},
            {"within_ratio", s.within_ratio()},
            {"median_abs_error_m", s.median_abs_error_m},
            {"mean_abs_error_m", s.mean_abs_error_m}};
}

std::string stats_line(const RangeErrorStats& s) {
    char line[160];
    std::snprintf(line, sizeof(line),
                  "%8zu rays  hit %6.2f %%  within %6.2f %%  median %6.2f cm  "
                  "mean %6.2f cm",
                  s.rays, 100.0 * s.hit_ratio(), 100.0 * s.within_ratio(),
                  100.0 * s.median_abs_error_m, 100.0 * s.mean_abs_error_m);
    return line;
}

}  // namespace

RangeErrorStats score_scan_ranges(const RayCaster& surface, const Eigen::Vector3d& origin_world_m,
                                  const std::vector<Eigen::Vector3f>& points_sensor,
                                  const Eigen::Isometry3d& T_world_sensor,
                                  const HeldoutConfig& config, std::vector<float>* abs_errors_m) {
    check_config(config);
    // The sensor in the mesh's frame, in double: world poses may be UTM-sized.
    const Eigen::Vector3d sensor_mesh = T_world_sensor.translation() - origin_world_m;
    const Eigen::Matrix3d R_world_sensor = T_world_sensor.linear();
    const std::size_t n = points_sensor.size();
    const std::size_t num_blocks = (n + kRaysPerBlock - 1) / kRaysPerBlock;
    struct Block {
        std::size_t rays = 0, hits = 0, within = 0;
        std::vector<float> errors;
    };
    std::vector<Block> blocks(num_blocks);
    tbb::parallel_for(std::size_t(0), num_blocks, [&](std::size_t b) {
        Block& block = blocks[b];
        const std::size_t end = std::min(n, (b + 1) * kRaysPerBlock);
        for (std::size_t i = b * kRaysPerBlock; i < end; ++i) {
            const Eigen::Vector3d p = points_sensor[i].cast<double>();
            if (!p.allFinite()) continue;
            const double measured_m = p.norm();
            if (!(measured_m >= config.min_range_m && measured_m <= config.max_range_m) ||
                measured_m == 0.0) {
                continue;
            }
            ++block.rays;
            const Eigen::Vector3d direction = R_world_sensor * (p / measured_m);
            const RayHit hit =
                surface.cast(sensor_mesh, direction, 0.0, measured_m + config.overshoot_m);
            if (!hit.hit()) continue;
            ++block.hits;
            const double error_m = std::abs(hit.distance_m - measured_m);
            block.within += error_m <= config.threshold_m;
            block.errors.push_back(static_cast<float>(error_m));
        }
    });
    RangeErrorStats stats;
    std::vector<float> errors;
    errors.reserve(n);
    for (const Block& block : blocks) {
        stats.rays += block.rays;
        stats.hits += block.hits;
        stats.within += block.within;
        errors.insert(errors.end(), block.errors.begin(), block.errors.end());
    }
    if (abs_errors_m) abs_errors_m->insert(abs_errors_m->end(), errors.begin(), errors.end());
    summarise(errors, stats);
    return stats;
}

HeldoutReport evaluate_heldout(const TriangleMesh& mesh, const ScanSequence& sequence,
                               const std::vector<std::size_t>& frames, const HeldoutConfig& config,
                               const ScanPreparation& prepare) {
    check_config(config);
    if (frames.empty()) throw ConfigError("no held-out frames to score");
    for (const std::size_t f : frames) {
        if (f >= sequence.size()) {
            throw ConfigError("held-out frame " + std::to_string(f) + " is outside the sequence '" +
                              sequence.directory().string() + "' of " +
                              std::to_string(sequence.size()) + " scans (frames count from 0)");
        }
    }
    if (mesh.triangles.empty()) {
        throw ConfigError("the map's mesh has no triangles: nothing to cast held-out rays into");
    }
    const RayCaster caster(mesh);
    HeldoutReport report;
    report.config = config;
    std::vector<float> all_errors;
    for (const std::size_t f : frames) {
        Scan scan = sequence.load(f);
        if (prepare) prepare(f, scan);
        HeldoutScan result;
        result.frame = f;
        result.source = scan.source;
        result.stats = score_scan_ranges(caster, mesh.origin_world_m, scan.points_sensor,
                                         scan.T_world_sensor, config, &all_errors);
        report.total.rays += result.stats.rays;
        report.total.hits += result.stats.hits;
        report.total.within += result.stats.within;
        report.scans.push_back(std::move(result));
    }
    summarise(all_errors, report.total);
    return report;
}

std::vector<std::size_t> holdout_frames(std::size_t num_scans, int every) {
    if (every < 2) {
        throw ConfigError("--holdout-every " + std::to_string(every) +
                          " must be at least 2 (every N-th scan is held out)");
    }
    std::vector<std::size_t> frames;
    for (std::size_t i = std::size_t(every) - 1; i < num_scans; i += std::size_t(every)) {
        frames.push_back(i);
    }
    return frames;
}

std::vector<std::size_t> parse_frame_list(const std::string& text, std::size_t num_scans) {
    std::vector<std::size_t> frames;
    const auto bad = [&](const std::string& item, const std::string& why) {
        return ConfigError("frame list '" + text + "': '" + item + "' " + why +
                           " (use indices and first:last[:step] ranges, e.g. 2,5,8 or 2:52:3)");
    };
    const auto number = [&](const std::string& item, const std::string& s) {
        if (s.empty() || s.find_first_not_of("0123456789") != std::string::npos) {
            throw bad(item, "is not a frame index");
        }
        const unsigned long long v = std::stoull(s);
        if (v >= num_scans) {
            throw bad(item, "is outside the sequence of " + std::to_string(num_scans) +
                                " scans (frames count from 0)");
        }
        return std::size_t(v);
    };
    std::size_t start = 0;
    while (start <= text.size()) {
        std::size_t comma = text.find(',', start);
        if (comma == std::string::npos) comma = text.size();
        const std::string item = text.substr(start, comma - start);
        start = comma + 1;
        if (item.empty()) throw bad(item, "is empty");
        std::vector<std::string> parts;
        std::size_t p = 0;
        while (true) {
            const std::size_t colon = item.find(':', p);
            parts.push_back(item.substr(p, colon == std::string::npos ? colon : colon - p));
            if (colon == std::string::npos) break;
            p = colon + 1;
        }
        if (parts.size() == 1) {
            frames.push_back(number(item, parts[0]));
        } else if (parts.size() <= 3) {
            const std::size_t first = number(item, parts[0]);
            const std::size_t last = number(item, parts[1]);
            std::size_t step = 1;
            if (parts.size() == 3) {
                if (parts[2].empty() ||
                    parts[2].find_first_not_of("0123456789") != std::string::npos ||
                    std::stoull(parts[2]) == 0) {
                    throw bad(item, "has a step that is not a positive integer");
                }
                step = std::stoull(parts[2]);
            }
            if (last < first) throw bad(item, "ends before it starts");
            for (std::size_t f = first; f <= last; f += step) frames.push_back(f);
        } else {
            throw bad(item, "has too many ':'");
        }
        if (comma == text.size()) break;
    }
    std::sort(frames.begin(), frames.end());
    frames.erase(std::unique(frames.begin(), frames.end()), frames.end());
    return frames;
}

std::string format_heldout(const HeldoutReport& report) {
    char head[200];
    std::snprintf(head, sizeof(head),
                  "held-out rays (%zu scans; within = |range error| <= %.0f cm, misses fail):\n",
                  report.scans.size(), 100.0 * report.config.threshold_m);
    std::string text = head;
    text += "  all        " + stats_line(report.total) + "\n";
    for (const HeldoutScan& scan : report.scans) {
        char label[32];
        std::snprintf(label, sizeof(label), "  frame %-4zu ", scan.frame);
        text += label + stats_line(scan.stats) + "\n";
    }
    return text;
}

std::string heldout_to_json(const HeldoutReport& report, int indent) {
    nlohmann::json scans = nlohmann::json::array();
    for (const HeldoutScan& scan : report.scans) {
        nlohmann::json s = stats_json(scan.stats);
        s["frame"] = scan.frame;
        s["source"] = scan.source.string();
        scans.push_back(s);
    }
    const nlohmann::json json = {
        {"threshold_m", report.config.threshold_m}, {"min_range_m", report.config.min_range_m},
        {"max_range_m", report.config.max_range_m}, {"overshoot_m", report.config.overshoot_m},
        {"total", stats_json(report.total)},        {"scans", scans}};
    return json.dump(indent);
}

}  // namespace shine
