// Tiled mapping on Dask (docs/tiles.md): scripts/shine_dask_tiles.py maps a small simulated street
// as 40 m tiles (10 m overlap) on a local cluster of 4 worker processes and merges them with
// `shine merge`; the single-process `shine map --mode incremental` maps the same street with the
// same settings. The merged mesh must score no more than 1 F-score point below the single run
// (issue 8's bound), and the merged SDF must show no seam at the tile borders: along lines
// crossing a border near the surface, the change between neighbouring samples at the border is
// compared with the changes inside the tiles. A second test checks `shine merge`'s refusals of
// incompatible tiles and bad input.
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "cli_test_support.hpp"
#include "shine/model/map_file.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {

// The street: 10 frames (10 m of driving from x = 0 along the road, y ~ 0.5, ground at z = 0),
// seen up to 60 m. With 40 m tiles anchored at the map origin (0, 0) the tile borders x = 0 and
// y = 0 cross the road right under the trajectory; 8 tiles receive points.
constexpr int kFrames = 10;
constexpr int kStreetSeed = 1;
constexpr double kTileSizeM = 40.0;
constexpr double kOverlapM = 10.0;
constexpr int kLocalWorkers = 4;
// Issue 8: the tiled result scores within 1 F-score point of the single-process run. Both runs
// use kConfigYaml, the defaults before the speed work (issue 6): 100 steps per scan at the
// learning rate 0.01 on scans thinned to 0.05 m, not the default 40 steps at 0.02 on scans thinned
// to 0.2 m; and 250 consolidation steps instead of 1000, which each of the 8 tiles runs (the test
// took 160 s alone with 1000, 91 s with 250). The seam check below compares the SDF's largest
// changes at the borders with those inside the tiles, 15 cm above the road, outside the surface
// band: there the default's field, trained on the thinner scans with fewer steps, varies by up to
// 28-33 mm between samples 5 cm apart (17 mm with kConfigYaml), and the control's 3 cm step would
// not stand out. Each tile spends a scan's whole training budget on the part of the scan inside its
// crop box, so its rays get more steps than in the single run and the merged map scores higher
// (measured: +0.66 points here with 250 consolidation steps, +0.03 with 1000; +0.64 on the 50-frame
// street; docs/tiles.md): the bound is on the loss, kMaxFscoreLoss below the single run, and the
// gain is printed.
constexpr double kMaxFscoreLoss = 0.01;
constexpr const char* kConfigYaml =
    "incremental:\n  iterations_per_frame: 100\n  learning_rate: 0.01\n  consolidation_steps: 250\n"
    "preprocess:\n  voxel_downsample_m: 0.05\n";
// No scan is dropped on this street, so the union of the tiles' cells is the single run's map
// (measured: equal corner counts).
constexpr double kMaxCornerCountRatioGap = 0.001;

// Seam check (measurements in docs/tiles.md). SDF samples every 5 cm along lines crossing a
// border 15 cm above the flat road near the trajectory: 11 lines across x = 0 (y = -2.5 ... 2.5,
// 6 m either side) and 9 across y = 0 (x = 1 ... 9, 2.4 m either side, short of the curbs and
// road features beyond). The merged map mixes the two tiles' corners only in the cells just
// below the border (at most one level-2 cell, 0.8 m); a seam would show up there as a step or
// kink. The largest change between neighbouring samples within 0.8 m of the border must not
// exceed kSeamFactor times the largest change farther than 1.2 m from it on the same lines.
// Measured ratio: 0.80 with 250 consolidation steps, 0.59 with 1000 (the single run's map on
// the same lines, which has no border: 0.84, measured with 1000).
// A 3 cm step between the two sides, added to the merged SDF, must fail the check (it does,
// with a ratio near 2): the check can fail.
constexpr double kSampleStepM = 0.05;
constexpr double kHeightAboveRoadM = 0.15;
constexpr double kBorderZoneM = 0.8;  // one level-2 cell at 0.2 m leaves
constexpr double kInteriorFromM = 1.2;
constexpr double kSeamFactor = 1.5;
constexpr double kControlStepM = 0.03;

fs::path test_dir() { return test_dir_of("cli_tiles"); }

fs::path source_dir() { return fs::path(__FILE__).parent_path().parent_path(); }

CliResult run_command(const std::string& command) {
    const fs::path log = test_dir() / "last_command.log";
    const int status = std::system((command + " > '" + log.string() + "' 2>&1").c_str());
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, read_text(log)};
}

/// Largest |change| between neighbouring samples along lines, split by the distance of the
/// pair's midpoint from the border.
struct JumpStats {
    double border_max_m = 0.0;
    double interior_max_m = 0.0;
    std::size_t border_pairs = 0;
    std::size_t interior_pairs = 0;

    void add(const JumpStats& o) {
        border_max_m = std::max(border_max_m, o.border_max_m);
        interior_max_m = std::max(interior_max_m, o.interior_max_m);
        border_pairs += o.border_pairs;
        interior_pairs += o.interior_pairs;
    }
};

/// Samples the SDF along lines through the border at `border_m` on axis `axis` (0: the border
/// x = border_m, lines along x; 1: y = border_m, lines along y), `half_length_m` either side, one
/// line per value of `offsets_m` on the other axis. `step_m` is added to the height of the
/// samples beyond the border (0: none; the control's artificial seam).
JumpStats measure_jumps(const shine::NeuralSdf& sdf, int axis, double border_m,
                        double half_length_m, const std::vector<double>& offsets_m,
                        double step_m = 0.0) {
    JumpStats stats;
    const int n = static_cast<int>(std::lround(2.0 * half_length_m / kSampleStepM)) + 1;
    for (double offset : offsets_m) {
        std::vector<Eigen::Vector3f> points_map;
        std::vector<double> along;
        for (int i = 0; i < n; ++i) {
            const double t = border_m - half_length_m + i * kSampleStepM;
            const double z = kHeightAboveRoadM + (t >= border_m ? step_m : 0.0);
            const Eigen::Vector3d world(axis == 0 ? t : offset, axis == 0 ? offset : t, z);
            points_map.push_back((world - sdf.origin_world_m).cast<float>());
            along.push_back(t);
        }
        std::vector<float> values;
        std::vector<std::uint8_t> valid;
        sdf.query(points_map, shine::QueryMask::kLevel0, values, valid);
        for (int i = 0; i + 1 < n; ++i) {
            if (!valid[i] || !valid[i + 1]) continue;
            const double jump = std::abs(values[i + 1] - values[i]);
            const double from_border = std::abs(0.5 * (along[i] + along[i + 1]) - border_m);
            if (from_border <= kBorderZoneM) {
                stats.border_max_m = std::max(stats.border_max_m, jump);
                ++stats.border_pairs;
            } else if (from_border >= kInteriorFromM) {
                stats.interior_max_m = std::max(stats.interior_max_m, jump);
                ++stats.interior_pairs;
            }
        }
    }
    return stats;
}

/// The seam check's lines across the borders x = 0 and y = 0, pooled.
JumpStats measure_seams(const shine::NeuralSdf& sdf, double step_m = 0.0) {
    JumpStats stats = measure_jumps(
        sdf, 0, 0.0, 6.0, {-2.5, -2.0, -1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 2.0, 2.5}, step_m);
    stats.add(measure_jumps(sdf, 1, 0.0, 2.4, {1, 2, 3, 4, 5, 6, 7, 8, 9}, step_m));
    return stats;
}

}  // namespace

TEST(CliTiles, DaskTilesMatchSingleRunWithoutSeams) {
    const CliResult python = run_command("/usr/bin/python3 -c 'import distributed, numpy, yaml'");
    ASSERT_EQ(python.exit_code, 0)
        << "/usr/bin/python3 cannot import the Dask distributed module (or numpy/yaml): install "
           "the Debian packages python3-distributed and python3-numpy (scripts/setup.sh does)\n"
        << python.output;

    const fs::path street = test_dir() / "street";
    simulate_street(street, kFrames, kStreetSeed);
    // The tiled run on a local Dask cluster of 4 worker processes.
    const fs::path tiled = test_dir() / "tiled";
    fs::remove_all(tiled);
    const fs::path config = test_dir() / "config.yaml";
    std::ofstream(config) << kConfigYaml;
    const fs::path script = source_dir() / "scripts" / "shine_dask_tiles.py";
    const CliResult t =
        run_command("/usr/bin/python3 '" + script.string() + "' '" + street.string() + "' -o '" +
                    tiled.string() + "' --shine '" + SHINE_CLI_PATH + "' --local-workers " +
                    std::to_string(kLocalWorkers) + " --tile-size-m " + std::to_string(kTileSizeM) +
                    " --overlap-m " + std::to_string(kOverlapM) + " --threads-per-tile 1 -c '" +
                    config.string() + "'");
    ASSERT_EQ(t.exit_code, 0) << t.output;
    EXPECT_NE(t.output.find("local Dask cluster: 4 worker processes"), std::string::npos)
        << t.output;
    for (const char* f :
         {"map.vdb", "surface.vdb", "mesh.ply", "stats.json", "manifest.json", "tiles_run.json"}) {
        EXPECT_TRUE(fs::exists(tiled / f)) << f;
    }
    const nlohmann::json run = read_json(tiled / "tiles_run.json");
    ASSERT_GE(run.at("tiles").size(), 4u);
    bool border_x0 = false, border_y0 = false;  // cores meet at x = 0 and at y = 0
    for (const auto& a : run.at("tiles")) {
        const auto c = a.at("core_world_m").get<std::vector<double>>();
        border_x0 = border_x0 || c[0] == 0.0;
        border_y0 = border_y0 || c[1] == 0.0;
    }
    EXPECT_TRUE(border_x0 && border_y0);

    // The single-process run with the same settings.
    const fs::path single = test_dir() / "single";
    fs::remove_all(single);
    const CliResult s =
        run_shine("map '" + street.string() + "' -o '" + single.string() +
                      "' --mode incremental --threads 2 -q -c '" + config.string() + "'",
                  test_dir());
    ASSERT_EQ(s.exit_code, 0) << s.output;

    const nlohmann::json stats_tiled = read_json(tiled / "stats.json");
    const nlohmann::json stats_single = read_json(single / "stats.json");
    const double f_tiled = stats_tiled.at("eval").at("fscore").get<double>();
    const double f_single = stats_single.at("eval").at("fscore").get<double>();
    std::printf(
        "F-score at 10 cm: tiled %.4f, single %.4f (gap %+.2f points); tiles mapped in "
        "%.1f s, merged in %.1f s\n",
        f_tiled, f_single, 100.0 * (f_tiled - f_single),
        run.at("seconds").at("map_tiles").get<double>(),
        run.at("seconds").at("merge").get<double>());
    EXPECT_GE(f_tiled, f_single - kMaxFscoreLoss);
    const double corners_tiled = stats_tiled.at("map").at("corners").get<double>();
    const double corners_single = stats_single.at("map").at("corners").get<double>();
    EXPECT_LE(std::abs(corners_tiled / corners_single - 1.0), kMaxCornerCountRatioGap)
        << corners_tiled << " corners merged, " << corners_single << " in the single run";

    const shine::LoadedMap merged = shine::load_neural_map(tiled / "map.vdb");
    const JumpStats seams = measure_seams(merged.sdf);
    std::printf(
        "seam check: largest change between samples 5 cm apart: %.2f mm near the borders "
        "(%zu pairs), %.2f mm inside the tiles (%zu pairs), ratio %.2f\n",
        1000.0 * seams.border_max_m, seams.border_pairs, 1000.0 * seams.interior_max_m,
        seams.interior_pairs, seams.border_max_m / seams.interior_max_m);
    EXPECT_GT(seams.border_pairs, 500u);  // the lines lie in the mapped region
    EXPECT_GT(seams.interior_pairs, 1000u);
    EXPECT_LE(seams.border_max_m, kSeamFactor * seams.interior_max_m);

    // The control: the same lines with a 3 cm step at the borders fail the check.
    const JumpStats stepped = measure_seams(merged.sdf, kControlStepM);
    std::printf("control with a %.0f cm step: ratio %.2f\n", 100.0 * kControlStepM,
                stepped.border_max_m / stepped.interior_max_m);
    EXPECT_GT(stepped.border_max_m, kSeamFactor * stepped.interior_max_m);
}

TEST(CliTiles, MergeRejectsIncompatibleOrBadInput) {
    const fs::path dir = test_dir();
    const fs::path street = dir / "street";
    simulate_street(street, /*frames=*/2, kStreetSeed);
    const fs::path config = dir / "config.yaml";
    // Two steps a scan and ten consolidation steps: the maps need only exist (the default 1000
    // consolidation steps took most of this test's 28 s).
    std::ofstream(config) << "incremental:\n  iterations_per_frame: 2\n  consolidation_steps: "
                             "10\nmap:\n  origin_world_m: [0, 0, 0]\n";
    const fs::path far_config = dir / "far_config.yaml";
    std::ofstream(far_config) << "incremental:\n  iterations_per_frame: 2\n  "
                                 "consolidation_steps: 10\nmap:\n  origin_world_m: [1000, 0, "
                                 "0]\n";
    // a: the reference; b: another leaf size; c: batch mode (its decoder is trained, not the
    // frozen one); d: another origin.
    const std::string common = "' --no-eval -q --threads 2 ";
    const std::vector<std::pair<std::string, std::string>> maps = {
        {"a", "--mode incremental -c '" + config.string() + "'"},
        {"b", "--mode incremental --leaf-size-m 0.4 -c '" + config.string() + "'"},
        {"c", "--mode batch --iterations 5 -c '" + config.string() + "'"},
        {"d", "--mode incremental -c '" + far_config.string() + "'"}};
    for (const auto& [name, options] : maps) {
        fs::remove_all(dir / name);
        const CliResult r = run_shine(
            "map '" + street.string() + "' -o '" + (dir / name).string() + common + options, dir);
        ASSERT_EQ(r.exit_code, 0) << r.output;
    }
    const auto map_of = [&](const std::string& name) { return (dir / name / "map.vdb").string(); };
    const fs::path out = dir / "merged";
    fs::remove_all(out);
    const auto merge_two = [&](const std::string& second) {
        return run_shine("merge --tile '" + map_of("a") + ":-100,-100,0,100' --tile '" +
                             map_of(second) + ":0,-100,100,100' -o '" + out.string() + "'",
                         dir);
    };

    // One tile on its own is a valid merge: the map comes back with the same corners.
    CliResult r = run_shine(
        "merge --tile '" + map_of("a") + ":-inf,-inf,inf,inf' -o '" + out.string() + "'", dir);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_EQ(read_json(out / "stats.json").at("map").at("corners"),
              read_json(dir / "a" / "stats.json").at("map").at("corners"));
    fs::remove_all(out);

    // Incompatible tiles: the error names the file and the setting; nothing is written.
    for (const auto& [second, setting] : std::vector<std::pair<std::string, std::string>>{
             {"b", "leaf size"}, {"c", "decoder (weight"}, {"d", "origin"}}) {
        r = merge_two(second);
        EXPECT_EQ(r.exit_code, 1) << r.output;
        EXPECT_NE(r.output.find(map_of(second)), std::string::npos) << r.output;
        EXPECT_NE(r.output.find(setting), std::string::npos) << r.output;
        EXPECT_FALSE(fs::exists(out / "map.vdb"));
    }

    // Overlapping cores, a malformed tile, a missing file, a file that is not a neural map.
    r = run_shine("merge --tile '" + map_of("a") + ":-100,-100,10,100' --tile '" + map_of("b") +
                      ":0,-100,100,100' -o '" + out.string() + "'",
                  dir);
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("overlap"), std::string::npos) << r.output;
    r = run_shine("merge --tile '" + map_of("a") + ":1,2,3' -o '" + out.string() + "'", dir);
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("xmin,ymin,xmax,ymax"), std::string::npos) << r.output;
    r = run_shine(
        "merge --tile '" + (dir / "none.vdb").string() + ":0,0,1,1' -o '" + out.string() + "'",
        dir);
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("none.vdb"), std::string::npos) << r.output;
    r = run_shine("merge --tile '" + (dir / "a" / "surface.vdb").string() + ":0,0,1,1' -o '" +
                      out.string() + "'",
                  dir);
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("surface.vdb"), std::string::npos) << r.output;

    // A manifest with a bad entry names the manifest and the entry.
    const fs::path manifest = dir / "manifest.json";
    std::ofstream(manifest) << R"({"tiles": [{"map": "a/map.vdb", "core_world_m": [0, 0, 1]}]})";
    r = run_shine("merge --manifest '" + manifest.string() + "' -o '" + out.string() + "'", dir);
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("manifest.json"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("tile 0"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out / "map.vdb"));
}
