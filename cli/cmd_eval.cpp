// `shine eval`: quality of a predicted mesh against a reference mesh (DESIGN.md, "Evaluation
// protocol"): accuracy, completion, Chamfer-L1 in cm; precision, completion ratio, F-score in %.
#include <cstdio>
#include <memory>
#include <string>

#include "command_registry.hpp"
#include "shine/eval/mesh_metrics.hpp"
#include "shine/eval/metrics_report.hpp"
#include "shine/io/ply.hpp"

namespace shine::cli {
namespace {

struct EvalOptions {
    std::string pred_path;
    std::string ref_path;
    EvalConfig config;
    bool json = false;
};

int run_eval(const EvalOptions& options) {
    // read_ply_mesh throws IoError naming the file for missing or corrupt input.
    const TriangleMesh ref = read_ply_mesh(options.ref_path);
    const TriangleMesh pred = read_ply_mesh(options.pred_path);
    const MeshMetrics metrics = evaluate_meshes(pred, ref, options.config);
    if (options.json) {
        std::printf("%s\n", metrics_to_json(metrics).c_str());
    } else {
        std::printf("pred  %s\nref   %s\n%s", options.pred_path.c_str(), options.ref_path.c_str(),
                    format_metrics(metrics).c_str());
    }
    return 0;
}

const RegisterCommand kEvalCommand(50, [](CLI::App& app, Action& action) {
    auto options = std::make_shared<EvalOptions>();
    CLI::App* cmd = app.add_subcommand(
        "eval",
        "Compare a mesh with a reference mesh: accuracy, completion, Chamfer-L1 (cm), precision, "
        "completion ratio, F-score (%). Completion counts only reference faces marked observed.");
    cmd->add_option("--pred", options->pred_path, "predicted mesh (PLY)")->required();
    cmd->add_option("--ref", options->ref_path,
                    "reference mesh (PLY; optional uchar face property 'observed')")
        ->required();
    cmd->add_option("--threshold-m", options->config.threshold_m,
                    "distance threshold of precision and completion ratio, m (0.2 for noisy data)")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    cmd->add_option("--seed", options->config.seed, "seed of the surface sampling")
        ->capture_default_str();
    cmd->add_flag("--json", options->json, "print one JSON object (metres, ratios in [0, 1])");
    cmd->callback([options, &action] { action = [options] { return run_eval(*options); }; });
});

}  // namespace
}  // namespace shine::cli
