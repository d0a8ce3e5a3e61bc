// Plot rendering: axis ticks on linear and log axes, and the memory-vs-Chamfer figure (size, the
// series drawn in their colours, point order, errors).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "shine/bench/plot.hpp"
#include "shine/core/error.hpp"

using namespace shine;

namespace {

constexpr Rgb kShineRed{214, 39, 40};
constexpr Rgb kTsdfBlue{31, 119, 180};

BenchRow row(BenchMethod method, double size_m, double map_mb, double chamfer_cm) {
    BenchRow r;
    r.method = method;
    r.size_m = size_m;
    r.map_bytes = static_cast<std::size_t>(map_mb * 1e6);
    BenchMetrics m;
    m.chamfer_l1_m = chamfer_cm / 100.0;
    r.metrics = m;
    return r;
}

int count(const RgbImage& image, Rgb colour, int x0 = 0, int x1 = -1) {
    if (x1 < 0) x1 = image.width() - 1;
    int n = 0;
    for (int y = 0; y < image.height(); ++y) {
        for (int x = x0; x <= x1; ++x) n += image.at(x, y) == colour;
    }
    return n;
}

/// Mean x of the pixels of `colour` in the image.
double mean_x(const RgbImage& image, Rgb colour) {
    double sum = 0.0;
    int n = 0;
    for (int y = 0; y < image.height(); ++y) {
        for (int x = 0; x < image.width(); ++x) {
            if (image.at(x, y) == colour) {
                sum += x;
                ++n;
            }
        }
    }
    return n ? sum / n : -1.0;
}

}  // namespace

TEST(PlotTicks, LinearStepsAreNice) {
    EXPECT_EQ(axis_ticks(0.0, 10.0, false, 5), (std::vector<double>{0, 2, 4, 6, 8, 10}));
    const std::vector<double> t = axis_ticks(6.1, 17.9, false, 6);
    EXPECT_EQ(t, (std::vector<double>{8, 10, 12, 14, 16}));
    const std::vector<double> small = axis_ticks(0.0, 1.0, false, 4);
    EXPECT_EQ(small.size(), 5u);  // step 0.25
    EXPECT_DOUBLE_EQ(small[1], 0.25);
    EXPECT_TRUE(axis_ticks(1.0, 1.0, false).empty());
}

TEST(PlotTicks, LogAxisUsesOneTwoFive) {
    EXPECT_EQ(axis_ticks(0.8, 120.0, true), (std::vector<double>{1, 2, 5, 10, 20, 50, 100}));
    // Over less than a decade: every integer mantissa (and 1.5).
    EXPECT_EQ(axis_ticks(3.5, 9.5, true), (std::vector<double>{4, 5, 6, 7, 8, 9}));
    // Over more than four decades: whole decades only.
    EXPECT_EQ(axis_ticks(0.05, 2000.0, true), (std::vector<double>{0.1, 1, 10, 100, 1000}));
    EXPECT_TRUE(axis_ticks(-1.0, 10.0, true).empty());
    EXPECT_EQ(format_tick(0.2), "0.2");
    EXPECT_EQ(format_tick(20.0), "20");
    EXPECT_EQ(format_tick(2.5), "2.5");
}

TEST(MemoryVsChamfer, DrawsBothSeriesWithLegendAndLabels) {
    const std::vector<BenchRow> rows = {
        row(BenchMethod::kTsdf, 0.1, 55.7, 17.5),    row(BenchMethod::kShineVdb, 0.1, 9.0, 7.0),
        row(BenchMethod::kTsdf, 0.2, 19.7, 10.4),    row(BenchMethod::kShineVdb, 0.2, 3.0, 6.7),
        row(BenchMethod::kShineVdb, 1.0, 0.6, 15.0), row(BenchMethod::kTsdf, 1.0, 5.8, 17.2)};
    const RgbImage image = plot_memory_vs_chamfer(rows, 800, 500);
    EXPECT_EQ(image.width(), 800);
    EXPECT_EQ(image.height(), 500);
    // Lines, markers, labels and legend entries in both colours.
    EXPECT_GT(count(image, kShineRed), 500);
    EXPECT_GT(count(image, kTsdfBlue), 500);
    // ShineVDB's maps are smaller here: its ink sits left of the TSDF's on the log memory axis.
    EXPECT_LT(mean_x(image, kShineRed), mean_x(image, kTsdfBlue));
    // Axis text and frame in dark ink.
    EXPECT_GT(count(image, Rgb{30, 30, 30}), 2000);
    // Written as a PNG it is a real file.
    const auto path = std::filesystem::path(SHINE_TEST_TMP_DIR) / "bench_plot.png";
    std::filesystem::create_directories(path.parent_path());
    image.write_png(path);
    EXPECT_GT(std::filesystem::file_size(path), 1000u);
}

TEST(MemoryVsChamfer, OneMethodOrOnePointStillRenders) {
    const RgbImage one = plot_memory_vs_chamfer({row(BenchMethod::kTsdf, 0.2, 19.7, 10.4)});
    EXPECT_GT(count(one, kTsdfBlue), 50);
    EXPECT_EQ(count(one, kShineRed), 0);
}

TEST(MemoryVsChamfer, Errors) {
    BenchRow unevaluated = row(BenchMethod::kTsdf, 0.2, 19.7, 10.4);
    unevaluated.metrics.reset();
    EXPECT_THROW(plot_memory_vs_chamfer({unevaluated}), ConfigError);
    EXPECT_THROW(plot_memory_vs_chamfer({}), ConfigError);
    EXPECT_THROW(plot_memory_vs_chamfer({row(BenchMethod::kTsdf, 0.2, 0.0, 10.4)}), ConfigError)
        << "a zero-byte map cannot go on a log axis";
    EXPECT_THROW(plot_memory_vs_chamfer({row(BenchMethod::kTsdf, 0.2, 1.0, 1.0)}, 100, 100),
                 ConfigError);
}
