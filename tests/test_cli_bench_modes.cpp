// `shine bench --modes`: ShineVDB in incremental mode beside batch mode and the TSDF, through the
// executable on a tiny simulated street with held-out scans: every mode's row, its products, its
// held-out figures and wall time in bench.csv, bench.json, bench.md and the printed table; bad
// lists fail before anything is read or written.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "cli_test_support.hpp"
#include "shine/bench/bench_report.hpp"
#include "shine/bench/bench_runner.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {

fs::path test_dir() { return test_dir_of("bench_modes_cli"); }

CliResult run(const std::string& args) { return run_shine(args, test_dir()); }

/// The row of `method`; fails the test when there is none.
const shine::BenchRow* find_row(const std::vector<shine::BenchRow>& rows,
                                shine::BenchMethod method) {
    for (const shine::BenchRow& row : rows) {
        if (row.method == method) return &row;
    }
    ADD_FAILURE() << "no " << shine::method_name(method) << " row";
    return nullptr;
}

/// The bench's `method` row (its products in bench_out/`run_dir`) is the `shine map` run in
/// map_out: the same mesh byte for byte and the same held-out figures.
void expect_row_is_the_map_run(const fs::path& bench_out, const std::string& run_dir,
                               shine::BenchMethod method, const fs::path& map_out) {
    EXPECT_EQ(read_text(bench_out / run_dir / "mesh.ply"), read_text(map_out / "mesh.ply"));
    const std::vector<shine::BenchRow> rows =
        shine::rows_from_csv(read_text(bench_out / "bench.csv"), "bench.csv");
    const shine::BenchRow* row = find_row(rows, method);
    ASSERT_TRUE(row && row->heldout);
    const nlohmann::json heldout = read_json(map_out / "stats.json").at("heldout").at("total");
    EXPECT_EQ(row->heldout->rays, heldout.at("rays").get<std::size_t>());
    EXPECT_NEAR(row->heldout->within_ratio, heldout.at("within_ratio").get<double>(), 1e-9);
    EXPECT_NEAR(row->heldout->median_abs_error_m, heldout.at("median_abs_error_m").get<double>(),
                1e-9);
}

}  // namespace

TEST(BenchModesCli, IncrementalRowsBesideBatchAndTsdfOnHeldOutScans) {
    const fs::path street = test_dir() / "street";
    simulate_street(street, /*frames=*/6, /*seed=*/3);
    // A cheap incremental schedule: 4 scans of 5 steps, then 100 consolidation steps.
    const fs::path config = test_dir() / "cheap.yaml";
    std::ofstream(config) << "incremental:\n  iterations_per_frame: 5\n"
                             "  consolidation_steps: 100\n";
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    const CliResult r =
        run("bench '" + street.string() + "' -o '" + out.string() + "' -c '" + config.string() +
            "' --sizes-m 0.5 --iterations 50 --threads 2 --holdout-every 3 --no-eval -q");
    // With --holdout-every both modes run without --modes.
    ASSERT_EQ(r.exit_code, 0) << r.output;
    for (const char* f :
         {"shinevdb_0.5/map.vdb", "tsdf_0.5/tsdf.vdb", "shinevdb_incremental_0.5/map.vdb",
          "shinevdb_incremental_0.5/mesh.ply", "shinevdb_incremental_0.5/surface.vdb"}) {
        EXPECT_TRUE(fs::is_regular_file(out / f)) << f;
    }
    // The held-out table names both modes, with the wall-time column and each mode against the
    // TSDF.
    for (const char* text :
         {"ShineVDB batch", "ShineVDB incremental", "seconds", "S - T", "I - T"}) {
        EXPECT_NE(r.output.find(text), std::string::npos) << text << "\n" << r.output;
    }

    const std::vector<shine::BenchRow> rows =
        shine::rows_from_csv(read_text(out / "bench.csv"), "bench.csv");
    ASSERT_EQ(rows.size(), 3u);
    const shine::BenchRow* batch = find_row(rows, shine::BenchMethod::kShineVdb);
    const shine::BenchRow* tsdf = find_row(rows, shine::BenchMethod::kTsdf);
    const shine::BenchRow* incremental = find_row(rows, shine::BenchMethod::kShineVdbIncremental);
    ASSERT_TRUE(batch && tsdf && incremental);
    EXPECT_EQ(batch->iterations, 50u);
    EXPECT_EQ(incremental->iterations, 4u * 5u + 100u) << "4 scans of 5 steps, 100 to consolidate";
    for (const shine::BenchRow* row : {batch, tsdf, incremental}) {
        const std::string name = shine::method_name(row->method);
        EXPECT_EQ(row->frames, 4u) << name << ": scans 2 and 5 are held out";
        EXPECT_GT(row->seconds, 0.0) << name;
        EXPECT_TRUE(std::isfinite(row->seconds)) << name;
        EXPECT_GT(row->map_bytes, 0u) << name;
        ASSERT_TRUE(row->heldout) << name;
        EXPECT_EQ(row->heldout->rays, tsdf->heldout->rays) << name << ": the same rays score all";
        EXPECT_TRUE(std::isfinite(row->heldout->median_abs_error_m)) << name;
        EXPECT_LE(row->heldout->within_ratio, row->heldout->hit_ratio) << name;
    }
    EXPECT_EQ(incremental->file_bytes,
              fs::file_size(shine::bench_run_dir(out, incremental->method, 0.5) / "map.vdb"));
    // Incremental mode's 0.5 m map of four noise-free scans with 120 steps in all: most held-out
    // rays land on it and most within 10 cm (measured: hit 95.8 %, within 70.0 %, median 3.42 cm;
    // the TSDF 93.8 %, 53.4 %, 8.19 cm).
    EXPECT_GT(incremental->heldout->hit_ratio, 0.85);
    EXPECT_GT(incremental->heldout->within_ratio, 0.5);
    EXPECT_LT(incremental->heldout->median_abs_error_m, 0.08);

    // bench.json holds the same rows and the modes; bench.md the held-out table of both modes.
    const std::vector<shine::BenchRow> json_rows =
        shine::rows_from_json(read_text(out / "bench.json"), "bench.json");
    ASSERT_EQ(json_rows.size(), rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
        EXPECT_EQ(json_rows[i].method, rows[i].method);
        EXPECT_EQ(json_rows[i].seconds, rows[i].seconds);
        EXPECT_EQ(json_rows[i].heldout->within_ratio, rows[i].heldout->within_ratio);
    }
    const nlohmann::json j = read_json(out / "bench.json");
    EXPECT_EQ(j.at("modes"), nlohmann::json({"batch", "incremental"}));
    const std::string md = read_text(out / "bench.md");
    EXPECT_NE(md.find("| ShineVDB incremental | 0.5 m |"), std::string::npos) << md;
    EXPECT_NE(md.find("| within: ShineVDB incremental - TSDF |"), std::string::npos) << md;

    // Incremental mode alone: the TSDF row and its row, the same figures (deterministic for a
    // seed), no batch run.
    const fs::path out_incremental = test_dir() / "out_incremental";
    fs::remove_all(out_incremental);
    const CliResult alone = run("bench '" + street.string() + "' -o '" + out_incremental.string() +
                                "' -c '" + config.string() +
                                "' --sizes-m 0.5 --threads 2 --holdout-every 3 --modes incremental "
                                "--no-eval -q");
    ASSERT_EQ(alone.exit_code, 0) << alone.output;
    const std::vector<shine::BenchRow> alone_rows =
        shine::rows_from_csv(read_text(out_incremental / "bench.csv"), "bench.csv");
    ASSERT_EQ(alone_rows.size(), 2u);
    EXPECT_EQ(alone_rows[0].method, shine::BenchMethod::kTsdf);
    EXPECT_EQ(alone_rows[1].method, shine::BenchMethod::kShineVdbIncremental);
    ASSERT_TRUE(alone_rows[1].heldout);
    EXPECT_EQ(alone_rows[1].heldout->within_ratio, incremental->heldout->within_ratio);
    EXPECT_FALSE(fs::exists(out_incremental / "shinevdb_0.5"));
}

TEST(BenchModesCli, BatchRowIsWhatShineMapMakesAtItsDefaults) {
    // The batch row is `shine map`'s batch run: poses refined with the map, the held-out scans
    // placed with the corrections of the mapped scans around them. The same mesh byte for byte
    // and the same held-out figures.
    const fs::path street = test_dir() / "street_map";
    simulate_street(street, /*frames=*/6, /*seed=*/3);
    const fs::path map_out = test_dir() / "map_out";
    const fs::path bench_out = test_dir() / "bench_out";
    fs::remove_all(map_out);
    fs::remove_all(bench_out);
    const std::string common = " --iterations 50 --threads 2 --holdout-every 3 --no-eval";
    const CliResult mapped = run("map '" + street.string() + "' -o '" + map_out.string() +
                                 "' --leaf-size-m 0.5 -q" + common);
    ASSERT_EQ(mapped.exit_code, 0) << mapped.output;
    const CliResult bench = run("bench '" + street.string() + "' -o '" + bench_out.string() +
                                "' --sizes-m 0.5 --modes batch -q" + common);
    ASSERT_EQ(bench.exit_code, 0) << bench.output;

    ASSERT_TRUE(read_json(map_out / "stats.json").contains("refine"))
        << "pose refinement is on by default in batch mode";
    expect_row_is_the_map_run(bench_out, "shinevdb_0.5", shine::BenchMethod::kShineVdb, map_out);
}

TEST(BenchModesCli, IncrementalRowIsWhatShineMapMakesInIncrementalMode) {
    // The incremental row is `shine map --mode incremental`'s run: the kept scans' poses refined
    // in the consolidation, the held-out scans placed with the corrections of the mapped scans
    // around them. On a street with 5 cm / 0.3 deg of pose noise those corrections are
    // centimetres, so scoring at the given poses would differ (it did before the row took them).
    const fs::path street = test_dir() / "street_noisy";
    fs::remove_all(street);
    const CliResult sim = run("simulate -o '" + street.string() +
                              "' --frames 9 --seed 3 --no-progress --pose-noise-m 0.05 "
                              "--pose-noise-deg 0.3");
    ASSERT_EQ(sim.exit_code, 0) << sim.output;
    const fs::path config = test_dir() / "cheap_incremental.yaml";
    std::ofstream(config) << "incremental:\n  iterations_per_frame: 5\n"
                             "  consolidation_steps: 100\n";
    const fs::path map_out = test_dir() / "map_incremental";
    const fs::path bench_out = test_dir() / "bench_incremental";
    fs::remove_all(map_out);
    fs::remove_all(bench_out);
    const std::string common =
        " -c '" + config.string() + "' --threads 2 --holdout-every 3 --no-eval -q";
    const CliResult mapped = run("map '" + street.string() + "' -o '" + map_out.string() +
                                 "' --mode incremental --leaf-size-m 0.5" + common);
    ASSERT_EQ(mapped.exit_code, 0) << mapped.output;
    const CliResult bench = run("bench '" + street.string() + "' -o '" + bench_out.string() +
                                "' --sizes-m 0.5 --modes incremental" + common);
    ASSERT_EQ(bench.exit_code, 0) << bench.output;

    ASSERT_TRUE(read_json(map_out / "stats.json").contains("refine"))
        << "the consolidation refines given poses by default";
    expect_row_is_the_map_run(bench_out, "shinevdb_incremental_0.5",
                              shine::BenchMethod::kShineVdbIncremental, map_out);
}

TEST(BenchModesCli, BadModesFailBeforeAnything) {
    const fs::path out = test_dir() / "out_bad";
    for (const char* modes : {"''", "batch,", "online", "batch,batch"}) {
        fs::remove_all(out);
        const CliResult r = run("bench '" + (test_dir() / "no_such_dir").string() + "' -o '" +
                                out.string() + "' -q --modes " + modes);
        EXPECT_NE(r.exit_code, 0) << modes;
        EXPECT_NE(r.output.find("--modes"), std::string::npos) << modes << "\n" << r.output;
        EXPECT_EQ(r.output.find("no_such_dir"), std::string::npos)
            << "the mode list is checked before the data: " << r.output;
        EXPECT_FALSE(fs::exists(out));
    }
}
