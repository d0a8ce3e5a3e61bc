// Incremental mode through the `shine` executable: `shine map --mode incremental` on a small
// simulated street (products, per-frame timings, progress meshes, accuracy), `shine pretrain`
// writing a decoder that incremental mode loads, `shine forgetting` writing its report and
// picture, and bad settings that must fail with a message naming the problem.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli_test_support.hpp"
#include "shine/model/map_file.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {

// Measured on this street (6 frames, seed 3, 0.2 m leaves, incremental defaults): F-score 0.897
// at 10 cm (batch mode, 1500 steps: 0.907); the bound leaves room for other machines'
// floating-point differences.
constexpr double kMinFscore = 0.85;

fs::path test_dir() { return test_dir_of("incremental_cli"); }

CliResult run(const std::string& args) { return run_shine(args, test_dir()); }

// A small simulated street (made once per test process; not a pretraining seed).
const fs::path& street() {
    static const fs::path dir = [] {
        const fs::path d = test_dir() / "street";
        simulate_street(d, /*frames=*/6, /*seed=*/3);
        return d;
    }();
    return dir;
}

}  // namespace

TEST(IncrementalCli, MapsFrameByFrameWithProgressMeshes) {
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    const CliResult r = run("map " + street().string() + " -o " + out.string() +
                            " --mode incremental --mesh-every 2 --threads 2 -q");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("s/frame with 2 threads"), std::string::npos) << r.output;
    for (const char* f : {"map.vdb", "surface.vdb", "mesh.ply", "stats.json"}) {
        EXPECT_TRUE(fs::exists(out / f)) << f;
    }
    // Frames 1, 3 (every 2nd) and the last one, 5.
    for (const char* f : {"mesh_000001.ply", "mesh_000003.ply", "mesh_000005.ply"}) {
        EXPECT_TRUE(fs::exists(out / "progress" / f)) << f;
    }
    const nlohmann::json stats = read_json(out / "stats.json");
    EXPECT_EQ(stats.at("mode").get<std::string>(), "incremental");
    EXPECT_EQ(stats.at("frames").get<int>(), 6);
    const auto& inc = stats.at("incremental");
    EXPECT_EQ(inc.at("frames").size(), 6u);
    EXPECT_EQ(inc.at("progress_meshes").size(), 3u);
    EXPECT_GT(inc.at("median_seconds_per_frame").get<double>(), 0.0);
    EXPECT_EQ(inc.at("threads_used").get<int>(), 2);
    const double fscore = stats.at("eval").at("fscore").get<double>();
    std::printf("incremental F-score at 10 cm: %.4f, median %.3f s/frame\n", fscore,
                inc.at("median_seconds_per_frame").get<double>());
    EXPECT_GT(fscore, kMinFscore);
}

TEST(IncrementalCli, PretrainWritesADecoderThatIncrementalModeLoads) {
    const fs::path decoder = test_dir() / "decoder.yaml";
    fs::remove(decoder);
    const CliResult p = run("pretrain -o " + decoder.string() +
                            " --seeds 7 --frames 1 --iterations 30 --threads 2 -q --work-dir " +
                            (test_dir() / "work").string());
    ASSERT_EQ(p.exit_code, 0) << p.output;
    ASSERT_TRUE(fs::exists(decoder));
    std::ifstream in(decoder);
    std::stringstream text;
    text << in.rdbuf();
    EXPECT_NE(text.str().find("shine pretrain"), std::string::npos) << "provenance missing";

    const fs::path config = test_dir() / "config.yaml";
    std::ofstream(config) << "incremental:\n  decoder_weights: " << decoder.string()
                          << "\n  iterations_per_frame: 5\n";
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    const CliResult r =
        run("map " + street().string() + " -o " + out.string() +
            " --mode incremental --last-frame 1 --no-eval -q -c " + config.string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_EQ(read_json(out / "stats.json").at("incremental").at("decoder_weights"),
              decoder.string());
}

TEST(IncrementalCli, LoadsTheDecoderOfABatchMap) {
    // A batch run trains its decoder with its features; incremental mode can start from it.
    const fs::path batch = test_dir() / "batch";
    fs::remove_all(batch);
    const CliResult b = run("map " + street().string() + " -o " + batch.string() +
                            " --iterations 30 --last-frame 1 --no-eval --threads 2 -q");
    ASSERT_EQ(b.exit_code, 0) << b.output;
    const fs::path config = test_dir() / "map_decoder.yaml";
    std::ofstream(config) << "incremental:\n  decoder_weights: " << (batch / "map.vdb").string()
                          << "\n  iterations_per_frame: 5\n";
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    const CliResult r =
        run("map " + street().string() + " -o " + out.string() +
            " --mode incremental --last-frame 1 --no-eval --threads 2 -q -c " + config.string());
    ASSERT_EQ(r.exit_code, 0) << r.output;
    // The decoder stays frozen in incremental mode: the new map's decoder is the batch map's.
    const shine::LoadedMap from = shine::load_neural_map(batch / "map.vdb");
    const shine::LoadedMap made = shine::load_neural_map(out / "map.vdb");
    EXPECT_EQ(made.sdf.decoder.params(), from.sdf.decoder.params());

    // A .vdb that is not a ShineVDB map: a clear error naming it, and no map.
    const fs::path not_a_map = test_dir() / "surface_as_decoder.yaml";
    std::ofstream(not_a_map) << "incremental:\n  decoder_weights: "
                             << (batch / "surface.vdb").string() << "\n";
    fs::remove_all(out);
    const CliResult bad =
        run("map " + street().string() + " -o " + out.string() +
            " --mode incremental --last-frame 1 --no-eval -q -c " + not_a_map.string());
    EXPECT_NE(bad.exit_code, 0);
    EXPECT_NE(bad.output.find("surface.vdb"), std::string::npos) << bad.output;
    EXPECT_FALSE(fs::exists(out / "map.vdb"));
}

TEST(IncrementalCli, ForgettingExperimentWritesReportAndPicture) {
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    const CliResult r = run("forgetting " + street().string() + " -o " + out.string() +
                            " --iterations-per-frame 20 --threads 2 -q");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_TRUE(fs::exists(out / "forgetting.png"));
    EXPECT_TRUE(fs::exists(out / "regularized" / "mesh.ply"));
    EXPECT_TRUE(fs::exists(out / "unregularized" / "mesh.ply"));
    const nlohmann::json report = read_json(out / "forgetting.json");
    ASSERT_EQ(report.at("runs").size(), 2u);
    EXPECT_EQ(report.at("early_frames").get<int>(), 2);  // ceil(6 / 4)
    for (const auto& run : report.at("runs")) {
        EXPECT_GT(run.at("whole").at("fscore").get<double>(), 0.5) << run.at("name");
        EXPECT_GT(run.at("early").at("fscore").get<double>(), 0.5) << run.at("name");
    }
    EXPECT_GT(report.at("early_reference_area_m2").get<double>(), 10.0);
}

TEST(IncrementalCli, BadSettingsFailWithAClearMessage) {
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    CliResult r = run("map " + street().string() + " -o " + out.string() + " --mode online -q");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("incremental"), std::string::npos) << r.output;

    const fs::path config = test_dir() / "missing_decoder.yaml";
    std::ofstream(config) << "incremental:\n  decoder_weights: /no/such/decoder.yaml\n";
    r = run("map " + street().string() + " -o " + out.string() + " --mode incremental -q -c " +
            config.string());
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("/no/such/decoder.yaml"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out / "map.vdb"));

    std::ofstream(config) << "incremental:\n  no_such_key: 1\n";
    r = run("map " + street().string() + " -o " + out.string() + " --mode incremental -q -c " +
            config.string());
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("incremental.no_such_key"), std::string::npos) << r.output;
}
