#include "shine/eval/metrics_report.hpp"

#include <cstdio>
#include <nlohmann/json.hpp>

namespace shine {

std::string format_metrics(const MeshMetrics& m) {
    constexpr double kCmPerM = 100.0;
    constexpr double kPercent = 100.0;
    char buffer[1024];
    std::snprintf(buffer, sizeof(buffer),
                  "accuracy          %8.2f cm\n"
                  "completion        %8.2f cm\n"
                  "Chamfer-L1        %8.2f cm\n"
                  "precision         %8.2f %%   (threshold %.1f cm)\n"
                  "completion ratio  %8.2f %%\n"
                  "F-score           %8.2f %%\n"
                  "points            pred %zu (%zu for accuracy), ref %zu (%zu observed)\n"
                  "sampling          %.0f points/m^2; area pred %.1f m^2, ref %.1f m^2 "
                  "(%.1f m^2 observed)\n",
                  m.accuracy_m * kCmPerM, m.completion_m * kCmPerM, m.chamfer_l1_m * kCmPerM,
                  m.precision * kPercent, m.threshold_m * kCmPerM, m.completion_ratio * kPercent,
                  m.fscore * kPercent, m.pred_points, m.accuracy_points, m.ref_points,
                  m.ref_observed_points, m.sample_density_per_m2, m.pred_area_m2, m.ref_area_m2,
                  m.ref_observed_area_m2);
    return buffer;
}

std::string metrics_to_json(const MeshMetrics& m, int indent) {
    const nlohmann::ordered_json json = {
        {"accuracy_m", m.accuracy_m},
        {"completion_m", m.completion_m},
        {"chamfer_l1_m", m.chamfer_l1_m},
        {"precision", m.precision},
        {"completion_ratio", m.completion_ratio},
        {"fscore", m.fscore},
        {"threshold_m", m.threshold_m},
        {"sample_density_per_m2", m.sample_density_per_m2},
        {"pred_area_m2", m.pred_area_m2},
        {"ref_area_m2", m.ref_area_m2},
        {"ref_observed_area_m2", m.ref_observed_area_m2},
        {"pred_points", m.pred_points},
        {"accuracy_points", m.accuracy_points},
        {"ref_points", m.ref_points},
        {"ref_observed_points", m.ref_observed_points},
    };
    return json.dump(indent);
}

}  // namespace shine
