#include "shine/mapper/stage_profile.hpp"

#include <algorithm>
#include <cstdio>

#include "shine/core/median.hpp"

namespace shine {

const char* stage_name(Stage stage) {
    static constexpr const char* kNames[kNumStages] = {"load",       "preprocess", "allocate",
                                                       "normals",    "sample",     "train",
                                                       "importance", "bake",       "mesh"};
    return kNames[static_cast<int>(stage)];
}

double StageSeconds::sum() const {
    double total = 0.0;
    for (const double s : seconds) total += s;
    return total;
}

StageSeconds& StageSeconds::operator+=(const StageSeconds& other) {
    for (int i = 0; i < kNumStages; ++i) seconds[i] += other.seconds[i];
    return *this;
}

StageSeconds StageProfile::frame_medians() const {
    StageSeconds medians;
    std::vector<double> values(frames.size());
    for (int i = 0; i < kNumStages; ++i) {
        for (std::size_t f = 0; f < frames.size(); ++f) values[f] = frames[f].seconds[i];
        medians.seconds[i] = median(values);
    }
    return medians;
}

double StageProfile::median_frame_seconds() const {
    std::vector<double> values;
    values.reserve(frames.size());
    for (const StageSeconds& f : frames) values.push_back(f.sum());
    return median(values);
}

StageSeconds StageProfile::totals() const {
    StageSeconds total = run;
    for (const StageSeconds& f : frames) total += f;
    return total;
}

std::string StageProfile::format_table() const {
    const StageSeconds medians = frame_medians();
    const StageSeconds total = totals();
    const double all = total.sum();
    std::string out;
    char line[160];
    std::snprintf(line, sizeof(line), "profile (%d thread%s, %zu frames)\n", threads,
                  threads == 1 ? "" : "s", frames.size());
    out += line;
    std::snprintf(line, sizeof(line), "  %-11s %14s %12s %7s\n", "stage", "median ms/frame",
                  "total s", "share");
    out += line;
    for (int i = 0; i < kNumStages; ++i) {
        const Stage stage = static_cast<Stage>(i);
        std::snprintf(line, sizeof(line), "  %-11s %14.1f %12.2f %6.1f%%\n", stage_name(stage),
                      1e3 * medians[stage], total[stage],
                      all > 0.0 ? 100.0 * total[stage] / all : 0.0);
        out += line;
    }
    std::snprintf(line, sizeof(line), "  %-11s %14.1f %12.2f\n", "frame/all",
                  1e3 * median_frame_seconds(), all);
    out += line;
    return out;
}

}  // namespace shine
