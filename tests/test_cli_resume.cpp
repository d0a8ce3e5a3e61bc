// Checkpoint and resume (`shine map`, Ctrl-C / SIGTERM, `shine map --resume OUT`): a run stopped
// at any step and resumed gives the uninterrupted run's result bit for bit, in both modes and
// both feature precisions, whatever the thread count; a stopped run leaves no product behind;
// bad checkpoints and misuse fail with messages naming the file and the problem.
//
// The hidden option --interrupt-after N raises SIGINT at the N-th step (a scan while loading, an
// optimisation step, an incremental frame), so the real signal handler runs at a reproducible
// point.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "cli_test_support.hpp"
#include "shine/model/map_file.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {

constexpr int kInterruptedExit = 130;

fs::path test_dir() { return test_dir_of("cli_resume"); }

CliResult run(const std::string& args) { return run_shine(args, test_dir()); }

/// A 4-scan street and a configuration with short training, made once per test (ctest runs the
/// tests in parallel processes, each in its own directory).
const fs::path& street() {
    static const fs::path dir = [] {
        const fs::path d = test_dir() / "street";
        simulate_street(d, 4, 5);
        std::ofstream(d.parent_path() / "fast.yaml") << "incremental:\n"
                                                        "  iterations_per_frame: 25\n"
                                                        "training:\n"
                                                        "  iterations: 300\n";
        return d;
    }();
    return dir;
}

std::string fast_config() { return (street().parent_path() / "fast.yaml").string(); }

/// fast.yaml with 1024 samples a step in incremental mode: at 0.1 m leaves the consolidation's
/// 2000 steps of 8192 samples took 24 of an incremental run's 28 s, 4 s with 1024.
std::string fine_config() {
    const fs::path path = street().parent_path() / "fine.yaml";
    std::ofstream(path) << "incremental:\n"
                           "  iterations_per_frame: 25\n"
                           "  batch_size: 1024\n"
                           "training:\n"
                           "  iterations: 300\n";
    return path.string();
}

/// Without the evaluation against the street's reference (2 of a 4-scan run's 8 s): the
/// resumed run's mesh is compared with the reference run's byte for byte instead.
std::string map_args(const fs::path& out, const std::string& extra,
                     const std::string& config = fast_config()) {
    return "map '" + street().string() + "' -o '" + out.string() + "' -c '" + config +
           "' -q --no-eval " + extra;
}

/// Maps without interruption (once per configuration and process).
fs::path reference_run(const std::string& name, const std::string& extra,
                       const std::string& config = fast_config()) {
    const fs::path out = test_dir() / ("reference_" + name);
    fs::remove_all(out);
    const CliResult r = run(map_args(out, extra, config));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return out;
}

void expect_stopped_without_products(const CliResult& r, const fs::path& out) {
    EXPECT_EQ(r.exit_code, kInterruptedExit) << r.output;
    EXPECT_NE(r.output.find("checkpoint written to"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("shine map --resume"), std::string::npos) << r.output;
    EXPECT_TRUE(fs::exists(out / "checkpoint.bin"));
    for (const char* product : {"map.vdb", "surface.vdb", "mesh.ply", "stats.json"}) {
        EXPECT_FALSE(fs::exists(out / product)) << product;
    }
}

/// The resumed run's products equal the reference run's: the mesh byte for byte, the map's
/// features and decoder exactly (map.vdb itself differs by the file's random UUID).
void expect_same_result(const fs::path& resumed, const fs::path& reference) {
    EXPECT_FALSE(fs::exists(resumed / "checkpoint.bin")) << "a finished run removes it";
    const std::string mesh = read_text(resumed / "mesh.ply");
    ASSERT_FALSE(mesh.empty());
    EXPECT_TRUE(mesh == read_text(reference / "mesh.ply")) << "meshes differ";
    const shine::LoadedMap a = shine::load_neural_map(resumed / "map.vdb");
    const shine::LoadedMap b = shine::load_neural_map(reference / "map.vdb");
    EXPECT_EQ(a.sdf.octree.features().to_floats(), b.sdf.octree.features().to_floats());
    EXPECT_EQ(a.sdf.decoder.params(), b.sdf.decoder.params());
    EXPECT_EQ(read_json(resumed / "stats.json").at("map").at("corners"),
              read_json(reference / "stats.json").at("map").at("corners"));
}

}  // namespace

TEST(Resume, IncrementalRunStoppedAfterAFrameContinuesToTheSameMap) {
    const fs::path reference = reference_run("incremental", "--mode incremental --threads 2");
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    expect_stopped_without_products(
        run(map_args(out, "--mode incremental --threads 2 --interrupt-after 2")), out);
    // Resumed with another thread count: the run is deterministic for any.
    const CliResult r = run("map --resume '" + out.string() + "' -q --threads 1");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    expect_same_result(out, reference);
    const auto stats = read_json(out / "stats.json");
    EXPECT_TRUE(stats.at("resumed").get<bool>());
    EXPECT_EQ(stats.at("frames"), 4);
    EXPECT_EQ(stats.at("incremental").at("frames").size(), 4u);
}

TEST(Resume, IncrementalRunStoppedAfterItsLastFrameConsolidatesWhenResumed) {
    // The stop arrives after the 4th (last) scan, before the consolidation: the checkpoint holds
    // the online map, and the resumed run consolidates it as the uninterrupted run did.
    const fs::path reference = reference_run("incremental", "--mode incremental --threads 2");
    EXPECT_EQ(read_json(reference / "stats.json").at("incremental").at("consolidation").at("steps"),
              1000);
    const fs::path out = test_dir() / "out_last";
    fs::remove_all(out);
    const CliResult stopped =
        run(map_args(out, "--mode incremental --threads 2 --interrupt-after 4"));
    expect_stopped_without_products(stopped, out);
    EXPECT_NE(stopped.output.find("after frame 4 of 4"), std::string::npos) << stopped.output;
    const CliResult r = run("map --resume '" + out.string() + "' -q --threads 2");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    expect_same_result(out, reference);
    EXPECT_EQ(read_json(out / "stats.json").at("incremental").at("consolidation").at("steps"),
              1000);
}

TEST(Resume, FineLeafRunsResumeWithTheirLeafDefaults) {
    // At 0.1 m leaves both modes move defaults the user did not set (batch: every point, the
    // bake in the level-1 cells; incremental: its normals and 2000 consolidation steps). The
    // checkpoint stores every key's value; a resumed run must still tell the keys the user set
    // from the rest, or a batch run fails to resume ("the data now gives ... points") and an
    // incremental one maps with other settings.
    for (const std::string mode : {"batch", "incremental"}) {
        SCOPED_TRACE(mode);
        const std::string extra = "--mode " + mode + " --leaf-size-m 0.1 --threads 2";
        const fs::path reference = reference_run("fine_" + mode, extra, fine_config());
        const fs::path out = test_dir() / ("out_fine_" + mode);
        fs::remove_all(out);
        expect_stopped_without_products(
            run(map_args(
                out, extra + (mode == "batch" ? " --interrupt-after 103" : " --interrupt-after 2"),
                fine_config())),
            out);
        const CliResult r = run("map --resume '" + out.string() + "' -q --threads 2");
        ASSERT_EQ(r.exit_code, 0) << r.output;
        expect_same_result(out, reference);
        if (mode == "incremental") {
            EXPECT_EQ(
                read_json(out / "stats.json").at("incremental").at("consolidation").at("steps"),
                2000);
        }
    }
}

TEST(Resume, IncrementalRunReplayingEarlierScansContinuesToTheSameMap) {
    // With incremental.replay_frames 3 the scans before the stop train again after the resume,
    // with the normals they got when they were current. (A short consolidation: the frames'
    // replay is what the test is about.)
    const fs::path replay = test_dir() / "replay.yaml";
    std::ofstream(replay) << "incremental:\n"
                             "  iterations_per_frame: 25\n"
                             "  replay_frames: 3\n"
                             "  consolidation_steps: 100\n";
    const auto args = [&](const fs::path& out, const std::string& extra) {
        return "map '" + street().string() + "' -o '" + out.string() + "' -c '" + replay.string() +
               "' -q --no-eval --mode incremental --threads 2 " + extra;
    };
    const fs::path reference = test_dir() / "reference_replay";
    fs::remove_all(reference);
    const CliResult ref = run(args(reference, ""));
    ASSERT_EQ(ref.exit_code, 0) << ref.output;
    const fs::path out = test_dir() / "out_replay";
    fs::remove_all(out);
    expect_stopped_without_products(run(args(out, "--interrupt-after 3")), out);
    const CliResult r = run("map --resume '" + out.string() + "' -q --threads 1");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    expect_same_result(out, reference);
    // The replay changes the map: the same run without it differs.
    const fs::path plain = reference_run("incremental_plain", "--mode incremental --threads 2");
    EXPECT_FALSE(read_text(plain / "mesh.ply") == read_text(reference / "mesh.ply"));
}

// Batch mode polls for a stop after each scan but the last while loading (3 polls for the 4
// scans), once for each of the first map's 179 steps before the last round of pose refinement
// (at step 180 = 60 % of 300), then again while loading for the map itself (not when resuming)
// and after each of its training steps. The map at the refined poses starts from the first map
// (refine.warm_start: the noise-free street's later rounds move its scans by millimetres), so
// its steps are 181..300.
constexpr int kLoadPolls = 3;
constexpr int kRefinePolls = 179;
constexpr int kWarmStartStep = 180;

TEST(Resume, BatchRunStoppedDuringTrainingContinuesToTheSameMap) {
    const fs::path reference = reference_run("batch", "--threads 2");
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    const int step_220 = kLoadPolls + kRefinePolls + kLoadPolls + (220 - kWarmStartStep);
    const CliResult stopped =
        run(map_args(out, "--threads 2 --interrupt-after " + std::to_string(step_220)));
    expect_stopped_without_products(stopped, out);
    EXPECT_NE(stopped.output.find("after optimisation step 220 of 300"), std::string::npos)
        << stopped.output;
    const CliResult r = run("map --resume '" + out.string() + "' -q --threads 2");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    expect_same_result(out, reference);
    // The schedule's 300 steps, of which this map trained those after the first map's.
    const nlohmann::json stats = read_json(out / "stats.json");
    EXPECT_EQ(stats.at("iterations"), 300);
    EXPECT_EQ(stats.at("refine").at("warm_start").at("from_step"), kWarmStartStep);
    EXPECT_EQ(stats.at("refine").at("warm_start").at("steps_trained"), 300 - kWarmStartStep);
    EXPECT_EQ(read_text(out / "poses_refined.txt"), read_text(reference / "poses_refined.txt"));
}

TEST(Resume, BatchRunStoppedWhileRefiningPosesRefinesAgainToTheSameMap) {
    const fs::path reference = reference_run("batch", "--threads 2");
    const fs::path out = test_dir() / "out_refining";
    fs::remove_all(out);
    const CliResult stopped =
        run(map_args(out, "--threads 2 --interrupt-after " + std::to_string(kLoadPolls + 100)));
    expect_stopped_without_products(stopped, out);
    EXPECT_NE(stopped.output.find("while refining poses, after step 100 of 180"), std::string::npos)
        << stopped.output;
    EXPECT_FALSE(fs::exists(out / "poses_refined.txt"));
    const CliResult r = run("map --resume '" + out.string() + "' -q --threads 1");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    expect_same_result(out, reference);
    EXPECT_EQ(read_text(out / "poses_refined.txt"), read_text(reference / "poses_refined.txt"));
}

TEST(Resume, HalfPrecisionRunStoppedTwiceContinuesToTheSameMap) {
    const fs::path reference = reference_run("half", "--threads 2 --half-features");
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    // Stopped while loading, then again during training (the float32 master copy must survive;
    // the resumed run refines the poses again and does not poll while loading).
    expect_stopped_without_products(
        run(map_args(out, "--threads 2 --half-features --interrupt-after 2")), out);
    const CliResult again =
        run("map --resume '" + out.string() + "' -q --threads 2 --interrupt-after " +
            std::to_string(kLoadPolls + kRefinePolls + (250 - kWarmStartStep)));
    expect_stopped_without_products(again, out);
    EXPECT_NE(again.output.find("after optimisation step 250 of 300"), std::string::npos)
        << again.output;
    const CliResult r = run("map --resume '" + out.string() + "' -q --threads 1");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    expect_same_result(out, reference);
}

TEST(Resume, PeriodicCheckpointsDoNotChangeTheResultAndAreRemovedAtTheEnd) {
    const fs::path reference = reference_run("incremental_periodic", "--mode incremental");
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    // A checkpoint after every frame (the interval is a few milliseconds).
    const CliResult r = run(map_args(out, "--mode incremental --checkpoint-minutes 0.0001"));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    expect_same_result(out, reference);
}

TEST(Resume, RefusesToStartANewRunOverACheckpoint) {
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    expect_stopped_without_products(run(map_args(out, "--mode incremental --interrupt-after 1")),
                                    out);
    const auto before = fs::file_size(out / "checkpoint.bin");
    const CliResult r = run(map_args(out, "--mode incremental"));
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("holds an interrupted run"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("--resume"), std::string::npos) << r.output;
    EXPECT_EQ(fs::file_size(out / "checkpoint.bin"), before);
}

TEST(Resume, RejectsOptionsThatWouldChangeTheResult) {
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    expect_stopped_without_products(run(map_args(out, "--interrupt-after 1")), out);
    for (const std::string& option :
         std::vector<std::string>{"--seed 7", "--iterations 10", "--half-features",
                                  "--mode incremental", "'" + street().string() + "'"}) {
        const CliResult r = run("map --resume '" + out.string() + "' -q " + option);
        EXPECT_EQ(r.exit_code, 1) << option << ": " << r.output;
        EXPECT_NE(r.output.find("settings stored in its checkpoint"), std::string::npos)
            << r.output;
    }
}

TEST(Resume, MissingTruncatedOrForeignCheckpointsGiveClearErrors) {
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    fs::create_directories(out);
    CliResult r = run("map --resume '" + out.string() + "' -q");
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("has no checkpoint.bin"), std::string::npos) << r.output;

    expect_stopped_without_products(run(map_args(out, "--mode incremental --interrupt-after 2")),
                                    out);
    const std::string whole = read_text(out / "checkpoint.bin");
    const fs::path file = out / "checkpoint.bin";
    // Cut in the middle of the feature rows: the message names the file, the byte and the part.
    std::ofstream(file, std::ios::binary | std::ios::trunc) << whole.substr(0, whole.size() / 2);
    r = run("map --resume '" + out.string() + "' -q");
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("checkpoint '" + file.string() + "', byte"), std::string::npos)
        << r.output;
    EXPECT_NE(r.output.find("truncated"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out / "mesh.ply"));

    std::ofstream(file, std::ios::binary | std::ios::trunc) << "ply\nformat ascii 1.0\n";
    r = run("map --resume '" + out.string() + "' -q");
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find(file.string()), std::string::npos) << r.output;

    std::ofstream(file, std::ios::binary | std::ios::trunc);  // empty
    r = run("map --resume '" + out.string() + "' -q");
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find(file.string()), std::string::npos) << r.output;
}

TEST(Resume, DataThatChangedSinceTheCheckpointIsRejected) {
    const fs::path data = test_dir() / "street_copy";
    fs::remove_all(data);
    fs::copy(street(), data, fs::copy_options::recursive);
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    expect_stopped_without_products(
        run("map '" + data.string() + "' -o '" + out.string() + "' -c '" + fast_config() +
            "' -q --mode incremental --interrupt-after 3"),
        out);
    // Another street under the same name: the replayed scans no longer match the checkpoint.
    simulate_street(data, 4, 6);
    const CliResult r = run("map --resume '" + out.string() + "' -q");
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("did the data"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out / "mesh.ply"));
}
