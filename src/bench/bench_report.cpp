#include "shine/bench/bench_report.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "shine/core/error.hpp"

namespace shine {
namespace {

using json = nlohmann::json;

/// The header of files written before the held-out columns; they are still read.
constexpr const char* kCsvHeaderWithoutHeldout =
    "method,size_m,frames,iterations,map_bytes,file_bytes,seconds,seconds_per_frame,accuracy_m,"
    "completion_m,chamfer_l1_m,completion_ratio,precision,fscore";
constexpr const char* kCsvHeader =
    "method,size_m,frames,iterations,map_bytes,file_bytes,seconds,seconds_per_frame,accuracy_m,"
    "completion_m,chamfer_l1_m,completion_ratio,precision,fscore,heldout_rays,heldout_hit_ratio,"
    "heldout_within_ratio,heldout_median_abs_error_m,heldout_mean_abs_error_m";
constexpr std::size_t kCsvMetricFields = 14;
constexpr std::size_t kCsvFields = 19;
/// Check (c) looks at these resolutions.
constexpr double kCompletionSizesM[] = {0.1, 0.2};
/// Resolutions are the same when they differ by less than this (they come from one parsed list).
constexpr double kSizeToleranceM = 1e-9;

bool same_size(double a, double b) { return std::abs(a - b) < kSizeToleranceM; }

std::string shortest(double value) {
    char buffer[64];
    const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
    return std::string(buffer, result.ptr);
}

std::string format(const char* fmt, double a) {
    char buffer[64];
    std::snprintf(buffer, sizeof(buffer), fmt, a);
    return buffer;
}

/// The method with ShineVDB's mode spelled out: "ShineVDB batch", "ShineVDB incremental", "TSDF".
std::string mode_label(BenchMethod method) {
    return method == BenchMethod::kShineVdb ? "ShineVDB batch" : method_label(method);
}

bool is_shine(BenchMethod method) { return method != BenchMethod::kTsdf; }

std::string join_modes(const std::vector<std::string>& modes) {
    std::string out;
    for (const std::string& mode : modes) out += (out.empty() ? "" : ", ") + mode;
    return out;
}

std::string megabytes(std::size_t bytes) { return format("%.2f MB", bytes / 1e6); }
std::string centimetres(double m) { return format("%.2f cm", m * 100.0); }
std::string percent(double ratio) { return format("%.1f %%", ratio * 100.0); }

/// Rows of every method at each resolution, sorted by size.
struct SizePair {
    double size_m;
    const BenchRow* shine = nullptr;  ///< batch mode
    const BenchRow* tsdf = nullptr;
    const BenchRow* incremental = nullptr;
};

std::vector<SizePair> pair_by_size(const std::vector<BenchRow>& rows) {
    std::vector<SizePair> pairs;
    for (const BenchRow& row : rows) {
        auto it = std::find_if(pairs.begin(), pairs.end(),
                               [&](const SizePair& p) { return same_size(p.size_m, row.size_m); });
        if (it == pairs.end()) {
            pairs.push_back({row.size_m});
            it = pairs.end() - 1;
        }
        switch (row.method) {
            case BenchMethod::kShineVdb:
                it->shine = &row;
                break;
            case BenchMethod::kTsdf:
                it->tsdf = &row;
                break;
            case BenchMethod::kShineVdbIncremental:
                it->incremental = &row;
                break;
        }
    }
    std::sort(pairs.begin(), pairs.end(),
              [](const SizePair& a, const SizePair& b) { return a.size_m < b.size_m; });
    return pairs;
}

json metrics_json(const std::optional<BenchMetrics>& m) {
    if (!m) return nullptr;
    return {{"accuracy_m", m->accuracy_m},     {"completion_m", m->completion_m},
            {"chamfer_l1_m", m->chamfer_l1_m}, {"completion_ratio", m->completion_ratio},
            {"precision", m->precision},       {"fscore", m->fscore}};
}

json heldout_json(const std::optional<BenchHeldout>& h) {
    if (!h) return nullptr;
    return {{"rays", h->rays},
            {"hit_ratio", h->hit_ratio},
            {"within_ratio", h->within_ratio},
            {"median_abs_error_m", h->median_abs_error_m},
            {"mean_abs_error_m", h->mean_abs_error_m}};
}

json row_json(const BenchRow& row) {
    return {{"method", method_name(row.method)},
            {"size_m", row.size_m},
            {"frames", row.frames},
            {"iterations", row.iterations},
            {"map_bytes", row.map_bytes},
            {"file_bytes", row.file_bytes},
            {"seconds", row.seconds},
            {"seconds_per_frame", row.seconds_per_frame},
            {"eval", metrics_json(row.metrics)},
            {"heldout", heldout_json(row.heldout)}};
}

json brief_row_json(const std::optional<BenchRow>& row) {
    if (!row) return nullptr;
    return {{"method", method_name(row->method)},
            {"size_m", row->size_m},
            {"map_bytes", row->map_bytes},
            {"chamfer_l1_m", row->metrics ? json(row->metrics->chamfer_l1_m) : json(nullptr)}};
}

template <typename T>
T parse_number(const std::string& field, const std::string& what, const std::string& where) {
    T value{};
    const char* end = field.data() + field.size();
    const auto result = std::from_chars(field.data(), end, value);
    if (field.empty() || result.ec != std::errc() || result.ptr != end) {
        throw DataError(where + ": " + what + " '" + field + "' is not a number");
    }
    return value;
}

std::vector<std::string> split(const std::string& line, char separator) {
    std::vector<std::string> fields;
    std::string field;
    std::istringstream in(line);
    while (std::getline(in, field, separator)) fields.push_back(field);
    if (!line.empty() && line.back() == separator) fields.emplace_back();
    return fields;
}

}  // namespace

std::vector<BenchRatio> compute_ratios(const std::vector<BenchRow>& rows) {
    std::vector<BenchRatio> ratios;
    for (const SizePair& pair : pair_by_size(rows)) {
        if (!pair.shine || !pair.tsdf) continue;
        BenchRatio ratio;
        ratio.size_m = pair.size_m;
        ratio.memory_ratio = static_cast<double>(pair.shine->map_bytes) /
                             static_cast<double>(std::max<std::size_t>(pair.tsdf->map_bytes, 1));
        if (pair.shine->metrics && pair.tsdf->metrics) {
            const BenchMetrics& s = *pair.shine->metrics;
            const BenchMetrics& t = *pair.tsdf->metrics;
            if (t.chamfer_l1_m > 0.0) ratio.chamfer_ratio = s.chamfer_l1_m / t.chamfer_l1_m;
            ratio.fscore_difference = s.fscore - t.fscore;
        }
        if (pair.shine->heldout && pair.tsdf->heldout) {
            const BenchHeldout& s = *pair.shine->heldout;
            const BenchHeldout& t = *pair.tsdf->heldout;
            ratio.heldout_within_difference = s.within_ratio - t.within_ratio;
            ratio.heldout_hit_difference = s.hit_ratio - t.hit_ratio;
            if (t.median_abs_error_m > 0.0) {
                ratio.heldout_median_ratio = s.median_abs_error_m / t.median_abs_error_m;
            }
        }
        ratios.push_back(ratio);
    }
    return ratios;
}

BenchChecks compute_checks(const std::vector<BenchRow>& rows) {
    BenchChecks checks;
    const std::vector<SizePair> pairs = pair_by_size(rows);

    // (a) at every resolution where both ran.
    checks.shine_smaller_at_every_size = true;
    for (const SizePair& pair : pairs) {
        if (!pair.shine || !pair.tsdf) continue;
        checks.smaller_applicable = true;
        if (!(pair.shine->map_bytes < pair.tsdf->map_bytes)) {
            checks.shine_smaller_at_every_size = false;
            checks.sizes_where_shine_not_smaller.push_back(pair.size_m);
        }
    }
    if (!checks.smaller_applicable) checks.shine_smaller_at_every_size = false;

    // (b) the best TSDF result of the study, and the smallest ShineVDB map at least as good.
    for (const BenchRow& row : rows) {
        if (row.method != BenchMethod::kTsdf || !row.metrics) continue;
        const BenchRow* best = checks.best_tsdf ? &*checks.best_tsdf : nullptr;
        if (!best || row.metrics->chamfer_l1_m < best->metrics->chamfer_l1_m ||
            (row.metrics->chamfer_l1_m == best->metrics->chamfer_l1_m &&
             row.map_bytes < best->map_bytes)) {
            checks.best_tsdf = row;
        }
    }
    if (checks.best_tsdf) {
        const double bound_m = checks.best_tsdf->metrics->chamfer_l1_m;
        for (const BenchRow& row : rows) {
            if (row.method != BenchMethod::kShineVdb || !row.metrics) continue;
            if (!(row.metrics->chamfer_l1_m <= bound_m)) continue;
            if (!checks.smallest_good_shine ||
                row.map_bytes < checks.smallest_good_shine->map_bytes) {
                checks.smallest_good_shine = row;
            }
        }
        if (checks.smallest_good_shine) {
            checks.memory_ratio =
                static_cast<double>(checks.smallest_good_shine->map_bytes) /
                static_cast<double>(std::max<std::size_t>(checks.best_tsdf->map_bytes, 1));
            checks.memory_at_tsdf_quality_pass =
                *checks.memory_ratio <= kMaxMemoryRatioAtTsdfQuality;
        }
    }

    // (c) completion ratio at 0.1 m and 0.2 m.
    for (const double size_m : kCompletionSizesM) {
        for (const SizePair& pair : pairs) {
            if (!same_size(pair.size_m, size_m) || !pair.shine || !pair.tsdf) continue;
            if (!pair.shine->metrics || !pair.tsdf->metrics) continue;
            checks.completion.push_back({pair.size_m, pair.shine->metrics->completion_ratio,
                                         pair.tsdf->metrics->completion_ratio});
        }
    }
    return checks;
}

std::string rows_to_csv(const std::vector<BenchRow>& rows) {
    std::ostringstream out;
    out << kCsvHeader << "\n";
    for (const BenchRow& row : rows) {
        out << method_name(row.method) << ',' << shortest(row.size_m) << ',' << row.frames << ','
            << row.iterations << ',' << row.map_bytes << ',' << row.file_bytes << ','
            << shortest(row.seconds) << ',' << shortest(row.seconds_per_frame);
        if (row.metrics) {
            const BenchMetrics& m = *row.metrics;
            for (const double v : {m.accuracy_m, m.completion_m, m.chamfer_l1_m, m.completion_ratio,
                                   m.precision, m.fscore}) {
                out << ',' << shortest(v);
            }
        } else {
            out << ",,,,,,";
        }
        if (row.heldout) {
            const BenchHeldout& h = *row.heldout;
            out << ',' << h.rays;
            for (const double v :
                 {h.hit_ratio, h.within_ratio, h.median_abs_error_m, h.mean_abs_error_m}) {
                out << ',' << shortest(v);
            }
        } else {
            out << ",,,,,";
        }
        out << "\n";
    }
    return out.str();
}

std::vector<BenchRow> rows_from_csv(const std::string& text, const std::string& source) {
    std::istringstream in(text);
    std::string line;
    if (!std::getline(in, line) || (line != kCsvHeader && line != kCsvHeaderWithoutHeldout)) {
        throw DataError(source + ": the first line is not the bench CSV header '" +
                        std::string(kCsvHeader) + "'");
    }
    const std::size_t num_fields = line == kCsvHeader ? kCsvFields : kCsvMetricFields;
    std::vector<BenchRow> rows;
    int line_number = 1;
    while (std::getline(in, line)) {
        ++line_number;
        if (line.empty()) continue;
        const std::string where = source + ", line " + std::to_string(line_number);
        const std::vector<std::string> f = split(line, ',');
        if (f.size() != num_fields) {
            throw DataError(where + ": " + std::to_string(f.size()) + " fields, expected " +
                            std::to_string(num_fields));
        }
        BenchRow row;
        try {
            row.method = parse_method_name(f[0]);
        } catch (const DataError& e) {
            throw DataError(where + ": " + e.what());
        }
        row.size_m = parse_number<double>(f[1], "size_m", where);
        row.frames = parse_number<std::size_t>(f[2], "frames", where);
        row.iterations = parse_number<std::size_t>(f[3], "iterations", where);
        row.map_bytes = parse_number<std::size_t>(f[4], "map_bytes", where);
        row.file_bytes = parse_number<std::size_t>(f[5], "file_bytes", where);
        row.seconds = parse_number<double>(f[6], "seconds", where);
        row.seconds_per_frame = parse_number<double>(f[7], "seconds_per_frame", where);
        constexpr std::size_t kFirstMetric = 8;
        const auto any_set = [&f](std::size_t first, std::size_t last) {
            return std::any_of(f.begin() + first, f.begin() + last,
                               [](const std::string& s) { return !s.empty(); });
        };
        const bool any_metric = any_set(kFirstMetric, kCsvMetricFields);
        if (any_metric) {
            BenchMetrics m;
            m.accuracy_m = parse_number<double>(f[8], "accuracy_m", where);
            m.completion_m = parse_number<double>(f[9], "completion_m", where);
            m.chamfer_l1_m = parse_number<double>(f[10], "chamfer_l1_m", where);
            m.completion_ratio = parse_number<double>(f[11], "completion_ratio", where);
            m.precision = parse_number<double>(f[12], "precision", where);
            m.fscore = parse_number<double>(f[13], "fscore", where);
            row.metrics = m;
        }
        if (num_fields == kCsvFields && any_set(kCsvMetricFields, kCsvFields)) {
            BenchHeldout h;
            h.rays = parse_number<std::size_t>(f[14], "heldout_rays", where);
            h.hit_ratio = parse_number<double>(f[15], "heldout_hit_ratio", where);
            h.within_ratio = parse_number<double>(f[16], "heldout_within_ratio", where);
            h.median_abs_error_m = parse_number<double>(f[17], "heldout_median_abs_error_m", where);
            h.mean_abs_error_m = parse_number<double>(f[18], "heldout_mean_abs_error_m", where);
            row.heldout = h;
        }
        rows.push_back(row);
    }
    return rows;
}

std::string bench_to_json(const std::vector<BenchRow>& rows, const BenchInfo& info) {
    json root;
    root["data"] = info.data;
    root["reference"] = info.reference.empty() ? json(nullptr) : json(info.reference);
    root["config"] = info.config.empty() ? json(nullptr) : json(info.config);
    root["threads"] = info.threads;
    root["iterations"] = info.iterations >= 0 ? json(info.iterations) : json("auto");
    root["half_features"] = info.half_features;
    root["tsdf_trunc_voxels"] = info.trunc_voxels;
    root["holdout_every"] = info.holdout_every > 0 ? json(info.holdout_every) : json(nullptr);
    root["modes"] = info.modes;
    root["units"] = "map_bytes, file_bytes: bytes; seconds; *_m: metres; ratios in [0, 1]";
    root["rows"] = json::array();
    for (const BenchRow& row : rows) root["rows"].push_back(row_json(row));

    root["ratios"] = json::array();
    for (const BenchRatio& r : compute_ratios(rows)) {
        root["ratios"].push_back(
            {{"size_m", r.size_m},
             {"memory_ratio", r.memory_ratio},
             {"chamfer_ratio", r.chamfer_ratio ? json(*r.chamfer_ratio) : json(nullptr)},
             {"fscore_difference",
              r.fscore_difference ? json(*r.fscore_difference) : json(nullptr)},
             {"heldout_within_difference",
              r.heldout_within_difference ? json(*r.heldout_within_difference) : json(nullptr)},
             {"heldout_hit_difference",
              r.heldout_hit_difference ? json(*r.heldout_hit_difference) : json(nullptr)},
             {"heldout_median_ratio",
              r.heldout_median_ratio ? json(*r.heldout_median_ratio) : json(nullptr)}});
    }

    const BenchChecks c = compute_checks(rows);
    json checks;
    checks["a_shine_smaller_at_every_size"] = {
        {"applicable", c.smaller_applicable},
        {"pass", c.shine_smaller_at_every_size},
        {"sizes_where_shine_not_smaller_m", c.sizes_where_shine_not_smaller}};
    checks["b_memory_at_best_tsdf_quality"] = {
        {"applicable", c.best_tsdf.has_value()},
        {"pass", c.memory_at_tsdf_quality_pass},
        {"bound", kMaxMemoryRatioAtTsdfQuality},
        {"best_tsdf", brief_row_json(c.best_tsdf)},
        {"smallest_good_shinevdb", brief_row_json(c.smallest_good_shine)},
        {"memory_ratio", c.memory_ratio ? json(*c.memory_ratio) : json(nullptr)}};
    checks["c_completion_ratio"] = json::array();
    for (const CompletionComparison& cc : c.completion) {
        checks["c_completion_ratio"].push_back(
            {{"size_m", cc.size_m},
             {"shinevdb", cc.shine_completion_ratio},
             {"tsdf", cc.tsdf_completion_ratio},
             {"difference", cc.shine_completion_ratio - cc.tsdf_completion_ratio}});
    }
    root["checks"] = checks;
    return root.dump(2) + "\n";
}

std::vector<BenchRow> rows_from_json(const std::string& text, const std::string& source) {
    try {
        const json root = json::parse(text);
        std::vector<BenchRow> rows;
        for (const json& r : root.at("rows")) {
            BenchRow row;
            row.method = parse_method_name(r.at("method").get<std::string>());
            row.size_m = r.at("size_m").get<double>();
            row.frames = r.at("frames").get<std::size_t>();
            row.iterations = r.at("iterations").get<std::size_t>();
            row.map_bytes = r.at("map_bytes").get<std::size_t>();
            row.file_bytes = r.at("file_bytes").get<std::size_t>();
            row.seconds = r.at("seconds").get<double>();
            row.seconds_per_frame = r.at("seconds_per_frame").get<double>();
            const json& e = r.at("eval");
            if (!e.is_null()) {
                BenchMetrics m;
                m.accuracy_m = e.at("accuracy_m").get<double>();
                m.completion_m = e.at("completion_m").get<double>();
                m.chamfer_l1_m = e.at("chamfer_l1_m").get<double>();
                m.completion_ratio = e.at("completion_ratio").get<double>();
                m.precision = e.at("precision").get<double>();
                m.fscore = e.at("fscore").get<double>();
                row.metrics = m;
            }
            const auto h = r.find("heldout");  // absent in files from before held-out scans
            if (h != r.end() && !h->is_null()) {
                BenchHeldout held;
                held.rays = h->at("rays").get<std::size_t>();
                held.hit_ratio = h->at("hit_ratio").get<double>();
                held.within_ratio = h->at("within_ratio").get<double>();
                held.median_abs_error_m = h->at("median_abs_error_m").get<double>();
                held.mean_abs_error_m = h->at("mean_abs_error_m").get<double>();
                row.heldout = held;
            }
            rows.push_back(row);
        }
        return rows;
    } catch (const json::exception& e) {
        throw DataError(source + ": not a bench.json file: " + e.what());
    }
}

std::string format_rows_table(const std::vector<BenchRow>& rows) {
    std::string out;
    char line[256];
    std::snprintf(line, sizeof(line), "%-20s %6s %6s %10s %10s %8s %8s %8s %8s %8s %7s %7s %7s\n",
                  "method", "size", "iters", "map MB", "file MB", "seconds", "s/frame", "acc cm",
                  "comp cm", "CD cm", "CR %", "P %", "F %");
    out += line;
    std::vector<const BenchRow*> sorted;
    for (const BenchRow& row : rows) sorted.push_back(&row);
    std::stable_sort(sorted.begin(), sorted.end(), [](const BenchRow* a, const BenchRow* b) {
        return a->method != b->method ? a->method < b->method : a->size_m < b->size_m;
    });
    for (const BenchRow* row : sorted) {
        const std::string iterations =
            is_shine(row->method) ? std::to_string(row->iterations) : "-";
        std::snprintf(line, sizeof(line), "%-20s %6s %6s %10.2f %10.2f %8.1f %8.3f",
                      method_label(row->method).c_str(),
                      (format_size_m(row->size_m) + " m").c_str(), iterations.c_str(),
                      row->map_bytes / 1e6, row->file_bytes / 1e6, row->seconds,
                      row->seconds_per_frame);
        out += line;
        if (row->metrics) {
            const BenchMetrics& m = *row->metrics;
            std::snprintf(line, sizeof(line), " %8.2f %8.2f %8.2f %7.1f %7.1f %7.1f\n",
                          m.accuracy_m * 100, m.completion_m * 100, m.chamfer_l1_m * 100,
                          m.completion_ratio * 100, m.precision * 100, m.fscore * 100);
        } else {
            std::snprintf(line, sizeof(line), " %8s %8s %8s %7s %7s %7s\n", "-", "-", "-", "-", "-",
                          "-");
        }
        out += line;
    }
    return out;
}

std::string format_ratios_table(const std::vector<BenchRatio>& ratios) {
    std::string out;
    char line[160];
    std::snprintf(line, sizeof(line), "%6s %16s %17s %22s\n", "size", "memory S/T",
                  "Chamfer-L1 S/T", "F-score S-T (points)");
    out += line;
    for (const BenchRatio& r : ratios) {
        const std::string chamfer = r.chamfer_ratio ? format("%.3f", *r.chamfer_ratio) : "-";
        const std::string fscore =
            r.fscore_difference ? format("%+.1f", *r.fscore_difference * 100) : "-";
        std::snprintf(line, sizeof(line), "%6s %16.3f %17s %22s\n",
                      (format_size_m(r.size_m) + " m").c_str(), r.memory_ratio, chamfer.c_str(),
                      fscore.c_str());
        out += line;
    }
    return out;
}

std::string format_heldout_table(const std::vector<BenchRow>& rows) {
    std::string out;
    char line[240];
    const std::vector<SizePair> pairs = pair_by_size(rows);
    for (const SizePair& pair : pairs) {
        for (const BenchRow* row : {pair.tsdf, pair.shine, pair.incremental}) {
            if (!row || !row->heldout) continue;
            if (out.empty()) {
                std::snprintf(line, sizeof(line), "%-20s %6s %10s %9s %9s %10s %9s %9s %10s\n",
                              "method", "size", "rays", "hit %", "within %", "median cm", "mean cm",
                              "seconds", "map MB");
                out += line;
            }
            const BenchHeldout& h = *row->heldout;
            std::snprintf(
                line, sizeof(line), "%-20s %6s %10zu %9.2f %9.2f %10.2f %9.2f %9.1f %10.2f\n",
                mode_label(row->method).c_str(), (format_size_m(row->size_m) + " m").c_str(),
                h.rays, h.hit_ratio * 100, h.within_ratio * 100, h.median_abs_error_m * 100,
                h.mean_abs_error_m * 100, row->seconds, row->map_bytes / 1e6);
            out += line;
        }
        // Each ShineVDB mode against the TSDF of its size: differences, time and memory ratios.
        for (const auto& [name, shine] :
             {std::pair<const char*, const BenchRow*>{"S - T", pair.shine},
              {"I - T", pair.incremental}}) {
            if (!shine || !pair.tsdf || !shine->heldout || !pair.tsdf->heldout) continue;
            const BenchHeldout& s = *shine->heldout;
            const BenchHeldout& t = *pair.tsdf->heldout;
            std::snprintf(
                line, sizeof(line), "%-20s %6s %10s %+9.2f %+9.2f %+10.2f %+9.2f %9s %10s\n", name,
                (format_size_m(pair.size_m) + " m").c_str(), "", (s.hit_ratio - t.hit_ratio) * 100,
                (s.within_ratio - t.within_ratio) * 100,
                (s.median_abs_error_m - t.median_abs_error_m) * 100,
                (s.mean_abs_error_m - t.mean_abs_error_m) * 100,
                format("x%.1f", shine->seconds / std::max(pair.tsdf->seconds, 1e-9)).c_str(),
                format("x%.3f", static_cast<double>(shine->map_bytes) /
                                    std::max<std::size_t>(pair.tsdf->map_bytes, 1))
                    .c_str());
            out += line;
        }
    }
    return out;
}

std::string format_checks(const BenchChecks& c) {
    std::string out;
    out += "(a) ShineVDB's map is smaller than the TSDF map at every size: ";
    if (!c.smaller_applicable) {
        out += "n/a (no size with both methods)\n";
    } else if (c.shine_smaller_at_every_size) {
        out += "yes\n";
    } else {
        out += "NO, not at";
        for (const double s : c.sizes_where_shine_not_smaller) out += " " + format_size_m(s) + " m";
        out += "\n";
    }

    out += "(b) smallest ShineVDB map with Chamfer-L1 <= the best TSDF's is <= 1/4 of its bytes: ";
    if (!c.best_tsdf) {
        out += "n/a (no evaluated TSDF run)\n";
    } else {
        const BenchRow& t = *c.best_tsdf;
        out += c.memory_at_tsdf_quality_pass ? "yes\n" : "NO\n";
        out += "    best TSDF: " + format_size_m(t.size_m) + " m, Chamfer-L1 " +
               centimetres(t.metrics->chamfer_l1_m) + ", " + std::to_string(t.map_bytes) +
               " bytes (" + megabytes(t.map_bytes) + ")\n";
        if (c.smallest_good_shine) {
            const BenchRow& s = *c.smallest_good_shine;
            out += "    smallest ShineVDB at least as good: " + format_size_m(s.size_m) +
                   " m, Chamfer-L1 " + centimetres(s.metrics->chamfer_l1_m) + ", " +
                   std::to_string(s.map_bytes) + " bytes (" + megabytes(s.map_bytes) + ")\n";
            out += "    ratio " + format("%.3f", *c.memory_ratio) + " (bound " +
                   format("%.2f", kMaxMemoryRatioAtTsdfQuality) + ")\n";
        } else {
            out += "    no ShineVDB run reaches Chamfer-L1 <= " +
                   centimetres(t.metrics->chamfer_l1_m) + "\n";
        }
    }

    out += "(c) completion ratio, ShineVDB vs TSDF:";
    if (c.completion.empty()) out += " n/a (0.1 m / 0.2 m not evaluated for both)";
    out += "\n";
    for (const CompletionComparison& cc : c.completion) {
        out += "    " + format_size_m(cc.size_m) + " m: ShineVDB " +
               percent(cc.shine_completion_ratio) + ", TSDF " + percent(cc.tsdf_completion_ratio) +
               " (" +
               format("%+.1f", (cc.shine_completion_ratio - cc.tsdf_completion_ratio) * 100) +
               " points)\n";
    }
    return out;
}

std::string bench_to_markdown(const std::vector<BenchRow>& rows, const BenchInfo& info) {
    std::string out;
    out +=
        "| method | size | iterations | map | `.vdb` file | seconds | s/frame | accuracy | "
        "completion | Chamfer-L1 | completion ratio | precision | F-score |\n";
    out += "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
    std::vector<const BenchRow*> sorted;
    for (const BenchRow& row : rows) sorted.push_back(&row);
    std::stable_sort(sorted.begin(), sorted.end(), [](const BenchRow* a, const BenchRow* b) {
        return a->size_m != b->size_m ? a->size_m < b->size_m : a->method < b->method;
    });
    for (const BenchRow* row : sorted) {
        out += "| " + method_label(row->method) + " | " + format_size_m(row->size_m) + " m | " +
               (is_shine(row->method) ? std::to_string(row->iterations) : "-") + " | " +
               megabytes(row->map_bytes) + " | " + megabytes(row->file_bytes) + " | " +
               format("%.1f", row->seconds) + " | " + format("%.3f", row->seconds_per_frame);
        if (row->metrics) {
            const BenchMetrics& m = *row->metrics;
            out += " | " + centimetres(m.accuracy_m) + " | " + centimetres(m.completion_m) + " | " +
                   centimetres(m.chamfer_l1_m) + " | " + percent(m.completion_ratio) + " | " +
                   percent(m.precision) + " | " + percent(m.fscore) + " |\n";
        } else {
            out += " | - | - | - | - | - | - |\n";
        }
    }
    out +=
        "\n| size | memory ShineVDB / TSDF | Chamfer-L1 ShineVDB / TSDF | "
        "F-score ShineVDB - TSDF |\n";
    out += "| --- | --- | --- | --- |\n";
    for (const BenchRatio& r : compute_ratios(rows)) {
        out += "| " + format_size_m(r.size_m) + " m | " + format("%.3f", r.memory_ratio) + " | " +
               (r.chamfer_ratio ? format("%.3f", *r.chamfer_ratio) : "-") + " | " +
               (r.fscore_difference ? format("%+.1f points", *r.fscore_difference * 100) : "-") +
               " |\n";
    }
    const bool any_heldout = std::any_of(rows.begin(), rows.end(),
                                         [](const BenchRow& r) { return r.heldout.has_value(); });
    if (any_heldout) {
        out += "\nHeld-out scans (1 scan in " + std::to_string(info.holdout_every) +
               " not mapped; their rays cast into each mesh; within " +
               format("%g", info.heldout_threshold_m * 100) +
               " cm, a miss counts as a failure):\n\n";
        out +=
            "| method | size | rays | rays that hit | rays within | median error | mean error | "
            "seconds | map |\n";
        out += "| --- | --- | --- | --- | --- | --- | --- | --- | --- |\n";
        for (const BenchRow* row : sorted) {
            if (!row->heldout) continue;
            const BenchHeldout& h = *row->heldout;
            out += "| " + mode_label(row->method) + " | " + format_size_m(row->size_m) + " m | " +
                   std::to_string(h.rays) + " | " + format("%.2f %%", h.hit_ratio * 100) + " | " +
                   format("%.2f %%", h.within_ratio * 100) + " | " +
                   centimetres(h.median_abs_error_m) + " | " + centimetres(h.mean_abs_error_m) +
                   " | " + format("%.1f", row->seconds) + " | " + megabytes(row->map_bytes) +
                   " |\n";
        }
        // Per ShineVDB mode, its differences to the TSDF of each size.
        for (const BenchMethod method :
             {BenchMethod::kShineVdb, BenchMethod::kShineVdbIncremental}) {
            const std::string name =
                method == BenchMethod::kShineVdb ? "ShineVDB" : "ShineVDB incremental";
            std::string table;
            for (const SizePair& pair : pair_by_size(rows)) {
                const BenchRow* shine =
                    method == BenchMethod::kShineVdb ? pair.shine : pair.incremental;
                if (!shine || !pair.tsdf || !shine->heldout || !pair.tsdf->heldout) continue;
                const BenchHeldout& s = *shine->heldout;
                const BenchHeldout& t = *pair.tsdf->heldout;
                table +=
                    "| " + format_size_m(pair.size_m) + " m | " +
                    format("%+.2f points", (s.within_ratio - t.within_ratio) * 100) + " | " +
                    format("%+.2f points", (s.hit_ratio - t.hit_ratio) * 100) + " | " +
                    (t.median_abs_error_m > 0.0
                         ? format("%.3f", s.median_abs_error_m / t.median_abs_error_m)
                         : std::string("-")) +
                    " | " +
                    (pair.tsdf->seconds > 0.0 ? format("%.1f", shine->seconds / pair.tsdf->seconds)
                                              : std::string("-")) +
                    " |\n";
            }
            if (table.empty()) continue;
            out += "\n| size | within: " + name + " - TSDF | hit: " + name + " - TSDF | median " +
                   name + " / TSDF | seconds " + name +
                   " / TSDF |\n| --- | --- | --- | --- | --- |\n" + table;
        }
    }
    out += "\nChecks:\n\n```\n" + format_checks(compute_checks(rows)) + "```\n";
    out += "\nData `" + info.data + "`, reference `" +
           (info.reference.empty() ? std::string("none") : info.reference) + "`, " +
           (info.iterations >= 0 ? std::to_string(info.iterations) + " ShineVDB iterations"
                                 : std::string("ShineVDB iterations automatic per leaf size")) +
           (info.half_features ? ", float16 features" : "") + ", ShineVDB modes " +
           join_modes(info.modes) + ", " +
           (info.threads > 0 ? std::to_string(info.threads) : std::string("all")) +
           " threads, TSDF truncation " + format("%g", info.trunc_voxels) + " voxels" +
           (info.config.empty() ? "" : ", config `" + info.config + "`") + ".\n";
    return out;
}

}  // namespace shine
