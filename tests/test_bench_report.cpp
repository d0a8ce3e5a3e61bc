// The study's reports on hand-made rows: CSV and JSON round trips, ratios, the checks' logic
// (including "the smallest ShineVDB map at least as good as the best TSDF" and the case where no
// ShineVDB run is good enough), and the terminal tables.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include "shine/bench/bench_report.hpp"
#include "shine/core/error.hpp"

using namespace shine;

namespace {

BenchRow row(BenchMethod method, double size_m, std::size_t map_bytes, double chamfer_cm,
             double completion_ratio = 0.9, double fscore = 0.9) {
    BenchRow r;
    r.method = method;
    r.size_m = size_m;
    r.frames = 50;
    r.iterations = method == BenchMethod::kShineVdb ? 6000 : 0;
    r.map_bytes = map_bytes;
    r.file_bytes = map_bytes / 3;
    r.seconds = 12.345678901234567;
    r.seconds_per_frame = 0.1 / 3.0;
    BenchMetrics m;
    m.chamfer_l1_m = chamfer_cm / 100.0;
    m.accuracy_m = m.chamfer_l1_m * 0.8;
    m.completion_m = m.chamfer_l1_m * 1.2;
    m.completion_ratio = completion_ratio;
    m.precision = 0.95;
    m.fscore = fscore;
    r.metrics = m;
    return r;
}

constexpr auto S = BenchMethod::kShineVdb;
constexpr auto T = BenchMethod::kTsdf;

/// A study shaped like the street: TSDF best at 0.2 m (10.4 cm, 19.7 MB).
std::vector<BenchRow> study() {
    return {row(S, 0.1, 95'600'000, 6.9, 0.857, 0.908), row(T, 0.1, 55'700'000, 17.5, 0.688, 0.813),
            row(S, 0.2, 31'700'000, 6.7, 0.905, 0.909), row(T, 0.2, 19'720'000, 10.4, 0.827, 0.895),
            row(S, 0.5, 4'000'000, 9.0, 0.80, 0.80),    row(T, 0.5, 7'670'000, 13.4, 0.669, 0.737),
            row(S, 1.0, 1'500'000, 15.0, 0.5, 0.5),     row(T, 1.0, 5'780'000, 17.2, 0.418, 0.447)};
}

void expect_same_rows(const std::vector<BenchRow>& a, const std::vector<BenchRow>& b) {
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
        EXPECT_EQ(a[i].method, b[i].method) << i;
        EXPECT_EQ(a[i].size_m, b[i].size_m) << i;  // exact: numbers are written round-trip
        EXPECT_EQ(a[i].frames, b[i].frames) << i;
        EXPECT_EQ(a[i].iterations, b[i].iterations) << i;
        EXPECT_EQ(a[i].map_bytes, b[i].map_bytes) << i;
        EXPECT_EQ(a[i].file_bytes, b[i].file_bytes) << i;
        EXPECT_EQ(a[i].seconds, b[i].seconds) << i;
        EXPECT_EQ(a[i].seconds_per_frame, b[i].seconds_per_frame) << i;
        ASSERT_EQ(a[i].metrics.has_value(), b[i].metrics.has_value()) << i;
        if (!a[i].metrics) continue;
        EXPECT_EQ(a[i].metrics->accuracy_m, b[i].metrics->accuracy_m) << i;
        EXPECT_EQ(a[i].metrics->completion_m, b[i].metrics->completion_m) << i;
        EXPECT_EQ(a[i].metrics->chamfer_l1_m, b[i].metrics->chamfer_l1_m) << i;
        EXPECT_EQ(a[i].metrics->completion_ratio, b[i].metrics->completion_ratio) << i;
        EXPECT_EQ(a[i].metrics->precision, b[i].metrics->precision) << i;
        EXPECT_EQ(a[i].metrics->fscore, b[i].metrics->fscore) << i;
    }
    for (std::size_t i = 0; i < a.size(); ++i) {
        ASSERT_EQ(a[i].heldout.has_value(), b[i].heldout.has_value()) << i;
        if (!a[i].heldout) continue;
        EXPECT_EQ(a[i].heldout->rays, b[i].heldout->rays) << i;
        EXPECT_EQ(a[i].heldout->hit_ratio, b[i].heldout->hit_ratio) << i;
        EXPECT_EQ(a[i].heldout->within_ratio, b[i].heldout->within_ratio) << i;
        EXPECT_EQ(a[i].heldout->median_abs_error_m, b[i].heldout->median_abs_error_m) << i;
        EXPECT_EQ(a[i].heldout->mean_abs_error_m, b[i].heldout->mean_abs_error_m) << i;
    }
}

/// Held-out figures as a real walk gives them (0.2 m, every 3rd scan): ShineVDB hits more rays,
/// more of them within 10 cm, with a smaller median error.
void add_heldout(std::vector<BenchRow>& rows) {
    for (BenchRow& r : rows) {
        if (r.size_m != 0.2) continue;
        const bool shine = r.method == BenchMethod::kShineVdb;
        r.heldout = BenchHeldout{1'290'001, shine ? 0.9971 : 0.9878, shine ? 0.8911 : 0.8642,
                                 shine ? 0.0255 : 0.0266, shine ? 0.0709 : 0.0812};
    }
}

}  // namespace

TEST(BenchRow, NamesAndSizes) {
    EXPECT_EQ(method_name(S), "shinevdb");
    EXPECT_EQ(method_name(T), "tsdf");
    EXPECT_EQ(parse_method_name("tsdf"), T);
    EXPECT_THROW(parse_method_name("voxblox"), DataError);
    EXPECT_EQ(format_size_m(0.1), "0.1");
    EXPECT_EQ(format_size_m(0.25), "0.25");
    EXPECT_EQ(format_size_m(1.0), "1.0");
    EXPECT_EQ(format_size_m(2.0), "2.0");
}

TEST(BenchReport, CsvRoundTripIsExact) {
    std::vector<BenchRow> rows = study();
    rows[3].metrics.reset();  // a row without evaluation
    add_heldout(rows);
    const std::string csv = rows_to_csv(rows);
    EXPECT_EQ(
        csv.substr(0, csv.find('\n')),
        "method,size_m,frames,iterations,map_bytes,file_bytes,seconds,seconds_per_frame,accuracy_m,"
        "completion_m,chamfer_l1_m,completion_ratio,precision,fscore,heldout_rays,"
        "heldout_hit_ratio,heldout_within_ratio,heldout_median_abs_error_m,"
        "heldout_mean_abs_error_m");
    EXPECT_NE(csv.find("\ntsdf,0.2,50,0,19720000,6573333,"), std::string::npos) << csv;
    EXPECT_NE(csv.find(",,,,,,,1290001,0.9878,0.8642,0.0266,0.0812\n"), std::string::npos) << csv;
    EXPECT_NE(csv.find(",,,,,\n"), std::string::npos) << csv;
    expect_same_rows(rows_from_csv(csv), rows);
}

TEST(BenchReport, CsvWithoutHeldoutColumnsStillReads) {
    const std::vector<BenchRow> rows = rows_from_csv(
        "method,size_m,frames,iterations,map_bytes,file_bytes,seconds,seconds_per_frame,"
        "accuracy_m,completion_m,chamfer_l1_m,completion_ratio,precision,fscore\n"
        "tsdf,0.2,50,0,1,1,1,1,0.1,0.1,0.1,0.8,0.9,0.85\n");
    ASSERT_EQ(rows.size(), 1u);
    ASSERT_TRUE(rows[0].metrics);
    EXPECT_EQ(rows[0].metrics->fscore, 0.85);
    EXPECT_FALSE(rows[0].heldout);
}

TEST(BenchReport, CsvErrorsNameTheLine) {
    const std::string header = rows_to_csv({});
    EXPECT_THROW(rows_from_csv("method,size\n"), DataError);
    try {
        rows_from_csv(
            header + "tsdf,0.2,50,0,1,1,1,1,,,,,,,,,,,\ntsdf,abc,50,0,1,1,1,1,,,,,,,,,,,\n",
            "b.csv");
        FAIL();
    } catch (const DataError& e) {
        EXPECT_NE(std::string(e.what()).find("b.csv, line 3"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("abc"), std::string::npos) << e.what();
    }
    EXPECT_THROW(rows_from_csv(header + "tsdf,0.2,50\n"), DataError);
    EXPECT_THROW(rows_from_csv(header + "octomap,0.2,50,0,1,1,1,1,,,,,,,,,,,\n"), DataError);
    EXPECT_THROW(rows_from_csv(header + "tsdf,0.2,50,0,1,1,1,1,0.1,,,,,,,,,,\n"), DataError)
        << "metrics must be all present or all empty";
    EXPECT_THROW(rows_from_csv(header + "tsdf,0.2,50,0,1,1,1,1,,,,,,,10,0.5,,,\n"), DataError)
        << "held-out figures must be all present or all empty";
    EXPECT_THROW(rows_from_csv(header + "tsdf,0.2,50,0,1,1,1,1,,,,,,\n"), DataError)
        << "a row of the old width under the new header";
}

TEST(BenchReport, JsonRoundTripAndContents) {
    std::vector<BenchRow> rows = study();
    rows[0].metrics.reset();
    add_heldout(rows);
    BenchInfo info;
    info.data = "street";
    info.reference = "street/gt_mesh.ply";
    info.threads = 2;
    info.iterations = 6000;
    const std::string text = bench_to_json(rows, info);
    expect_same_rows(rows_from_json(text), rows);

    const nlohmann::json j = nlohmann::json::parse(text);
    EXPECT_EQ(j.at("data"), "street");
    EXPECT_TRUE(j.at("rows").at(0).at("eval").is_null());
    EXPECT_EQ(j.at("ratios").size(), 4u);
    const auto& b = j.at("checks").at("b_memory_at_best_tsdf_quality");
    EXPECT_TRUE(b.at("pass").get<bool>());
    EXPECT_EQ(b.at("best_tsdf").at("size_m").get<double>(), 0.2);
    EXPECT_EQ(b.at("smallest_good_shinevdb").at("size_m").get<double>(), 0.5);
    EXPECT_TRUE(j.at("rows").at(0).at("heldout").is_null());
    EXPECT_EQ(j.at("rows").at(2).at("heldout").at("rays").get<std::size_t>(), 1'290'001u);
    EXPECT_THROW(rows_from_json("{\"rows\": [{\"method\": \"tsdf\"}]}"), DataError);
    EXPECT_THROW(rows_from_json("not json"), DataError);
}

TEST(BenchReport, HeldoutRatiosAndTables) {
    std::vector<BenchRow> rows = study();
    add_heldout(rows);
    const std::vector<BenchRatio> ratios = compute_ratios(rows);
    ASSERT_EQ(ratios.size(), 4u);
    EXPECT_FALSE(ratios[0].heldout_within_difference) << "0.1 m held nothing out";
    ASSERT_TRUE(ratios[1].heldout_within_difference);
    EXPECT_NEAR(*ratios[1].heldout_within_difference, 0.8911 - 0.8642, 1e-12);
    EXPECT_NEAR(*ratios[1].heldout_hit_difference, 0.9971 - 0.9878, 1e-12);
    EXPECT_NEAR(*ratios[1].heldout_median_ratio, 0.0255 / 0.0266, 1e-12);

    const std::string table = format_heldout_table(rows);
    EXPECT_NE(table.find("89.11"), std::string::npos) << table;
    EXPECT_NE(table.find("+2.69"), std::string::npos) << table;  // within, ShineVDB - TSDF
    EXPECT_NE(table.find("-0.11"), std::string::npos) << table;  // median, cm
    EXPECT_EQ(format_heldout_table(study()), "") << "no held-out figures, no table";

    BenchInfo info;
    info.holdout_every = 3;
    const std::string md = bench_to_markdown(rows, info);
    EXPECT_NE(md.find("1 scan in 3 not mapped"), std::string::npos) << md;
    EXPECT_NE(md.find("| 0.2 m | +2.69 points | +0.93 points | 0.959 |"), std::string::npos) << md;
}

TEST(BenchChecks, SmallestShineAtLeastAsGoodAsBestTsdf) {
    const BenchChecks c = compute_checks(study());
    ASSERT_TRUE(c.best_tsdf);
    EXPECT_EQ(c.best_tsdf->size_m, 0.2);  // the lowest TSDF Chamfer-L1, 10.4 cm
    ASSERT_TRUE(c.smallest_good_shine);
    // 0.1, 0.2 and 0.5 m are <= 10.4 cm; 0.5 m has the smallest map. 1.0 m is smaller but worse.
    EXPECT_EQ(c.smallest_good_shine->size_m, 0.5);
    ASSERT_TRUE(c.memory_ratio);
    EXPECT_DOUBLE_EQ(*c.memory_ratio, 4'000'000.0 / 19'720'000.0);
    EXPECT_TRUE(c.memory_at_tsdf_quality_pass);
}

TEST(BenchChecks, MemoryRatioAboveAQuarterFails) {
    std::vector<BenchRow> rows = study();
    rows[4].map_bytes = 5'000'000;  // 5.0 / 19.72 = 0.254 > 1/4
    const BenchChecks c = compute_checks(rows);
    ASSERT_TRUE(c.memory_ratio);
    EXPECT_GT(*c.memory_ratio, 0.25);
    EXPECT_FALSE(c.memory_at_tsdf_quality_pass);
    rows[4].map_bytes = 4'930'000;  // exactly 1/4 passes
    EXPECT_TRUE(compute_checks(rows).memory_at_tsdf_quality_pass);
}

TEST(BenchChecks, EqualChamferCountsAsGoodEnough) {
    std::vector<BenchRow> rows = study();
    rows[6].metrics->chamfer_l1_m = rows[3].metrics->chamfer_l1_m;  // 1.0 m ties the best TSDF
    const BenchChecks c = compute_checks(rows);
    ASSERT_TRUE(c.smallest_good_shine);
    EXPECT_EQ(c.smallest_good_shine->size_m, 1.0);
}

TEST(BenchChecks, NoShineRunGoodEnough) {
    std::vector<BenchRow> rows = study();
    for (BenchRow& r : rows) {
        if (r.method == S) r.metrics->chamfer_l1_m = 0.2;  // all worse than 10.4 cm
    }
    const BenchChecks c = compute_checks(rows);
    ASSERT_TRUE(c.best_tsdf);
    EXPECT_FALSE(c.smallest_good_shine);
    EXPECT_FALSE(c.memory_ratio);
    EXPECT_FALSE(c.memory_at_tsdf_quality_pass);
    const std::string text = format_checks(c);
    EXPECT_NE(text.find("no ShineVDB run reaches Chamfer-L1 <= 10.40 cm"), std::string::npos)
        << text;
}

TEST(BenchChecks, SmallerAtEverySize) {
    std::vector<BenchRow> rows = study();
    BenchChecks c = compute_checks(rows);
    EXPECT_TRUE(c.smaller_applicable);
    EXPECT_FALSE(c.shine_smaller_at_every_size);  // 0.1 and 0.2 m are larger in this study
    EXPECT_EQ(c.sizes_where_shine_not_smaller, (std::vector<double>{0.1, 0.2}));
    rows[0].map_bytes = 1'000'000;
    rows[2].map_bytes = 1'000'000;
    c = compute_checks(rows);
    EXPECT_TRUE(c.shine_smaller_at_every_size);
    EXPECT_TRUE(c.sizes_where_shine_not_smaller.empty());
    rows[2].map_bytes = rows[3].map_bytes;  // equal is not smaller
    EXPECT_FALSE(compute_checks(rows).shine_smaller_at_every_size);
    // A size where only one method ran does not count; no common size: not applicable.
    c = compute_checks({row(S, 0.1, 1, 5.0), row(T, 0.2, 2, 5.0)});
    EXPECT_FALSE(c.smaller_applicable);
    EXPECT_FALSE(c.shine_smaller_at_every_size);
}

TEST(BenchChecks, CompletionAtTenAndTwentyCentimetres) {
    const BenchChecks c = compute_checks(study());
    ASSERT_EQ(c.completion.size(), 2u);
    EXPECT_EQ(c.completion[0].size_m, 0.1);
    EXPECT_DOUBLE_EQ(c.completion[0].shine_completion_ratio, 0.857);
    EXPECT_DOUBLE_EQ(c.completion[0].tsdf_completion_ratio, 0.688);
    EXPECT_EQ(c.completion[1].size_m, 0.2);
    const std::string text = format_checks(c);
    EXPECT_NE(text.find("0.1 m: ShineVDB 85.7 %, TSDF 68.8 % (+16.9 points)"), std::string::npos)
        << text;
}

TEST(BenchChecks, WithoutMetricsOnlyTheMemoryCheckApplies) {
    std::vector<BenchRow> rows = study();
    for (BenchRow& r : rows) r.metrics.reset();
    const BenchChecks c = compute_checks(rows);
    EXPECT_TRUE(c.smaller_applicable);
    EXPECT_FALSE(c.best_tsdf);
    EXPECT_TRUE(c.completion.empty());
    EXPECT_NE(format_checks(c).find("n/a (no evaluated TSDF run)"), std::string::npos);
}

TEST(BenchReport, RatiosAndTables) {
    const std::vector<BenchRatio> ratios = compute_ratios(study());
    ASSERT_EQ(ratios.size(), 4u);
    EXPECT_EQ(ratios[1].size_m, 0.2);
    EXPECT_DOUBLE_EQ(ratios[1].memory_ratio, 31.7 / 19.72);
    ASSERT_TRUE(ratios[1].chamfer_ratio);
    EXPECT_NEAR(*ratios[1].chamfer_ratio, 6.7 / 10.4, 1e-12);
    EXPECT_DOUBLE_EQ(*ratios[1].fscore_difference, 0.909 - 0.895);

    const std::string table = format_ratios_table(ratios);
    EXPECT_NE(table.find("0.2 m"), std::string::npos) << table;
    EXPECT_NE(table.find("1.608"), std::string::npos) << table;  // 31.7 / 19.72
    EXPECT_NE(table.find("+1.4"), std::string::npos) << table;   // F-score points

    const std::string rows_table = format_rows_table(study());
    EXPECT_NE(rows_table.find("ShineVDB"), std::string::npos);
    EXPECT_NE(rows_table.find("19.72"), std::string::npos) << rows_table;  // TSDF 0.2 m, MB
    EXPECT_NE(rows_table.find("10.40"), std::string::npos) << rows_table;  // its Chamfer, cm
    // ShineVDB rows come first, each method by ascending size.
    EXPECT_LT(rows_table.find("ShineVDB"), rows_table.find("TSDF"));
}

TEST(BenchReport, MarkdownHasTablesAndChecks) {
    BenchInfo info;
    info.data = "street";
    info.reference = "street/gt_mesh.ply";
    info.iterations = 6000;
    const std::string md = bench_to_markdown(study(), info);
    EXPECT_NE(md.find("| ShineVDB | 0.2 m | 6000 | 31.70 MB |"), std::string::npos) << md;
    EXPECT_NE(md.find("| TSDF | 0.2 m | - | 19.72 MB |"), std::string::npos) << md;
    EXPECT_NE(md.find("| 10.40 cm |"), std::string::npos) << md;
    EXPECT_NE(md.find("| 0.2 m | 1.608 | 0.644 | +1.4 points |"), std::string::npos) << md;
    EXPECT_NE(md.find("(b) smallest ShineVDB map"), std::string::npos) << md;
    EXPECT_NE(md.find("6000 ShineVDB iterations"), std::string::npos) << md;
    // Sizes ascend, ShineVDB before TSDF at each size.
    EXPECT_LT(md.find("| ShineVDB | 0.1 m"), md.find("| TSDF | 0.1 m"));
    EXPECT_LT(md.find("| TSDF | 0.1 m"), md.find("| ShineVDB | 0.2 m"));
}
