// Small raster line plots for reports: a generic x/y plot (linear or logarithmic x, one line and
// marker style per series, labelled points, ticks, axis labels, legend), and the study's figure,
// map memory against Chamfer-L1 (as the SHINE-Mapping paper plots it), built on it.
#pragma once

#include <string>
#include <vector>

#include "shine/bench/bench_row.hpp"
#include "shine/core/png_image.hpp"

namespace shine {

enum class MarkerShape { kDisc, kSquare };

/// One point of a series, with an optional text label drawn beside it.
struct PlotPoint {
    double x = 0.0;
    double y = 0.0;
    std::string label;
};

/// A line through its points in the given order, in one colour and marker shape.
struct PlotSeries {
    std::string name;  ///< legend entry
    Rgb colour;
    MarkerShape marker = MarkerShape::kDisc;
    std::vector<PlotPoint> points;
};

struct PlotSpec {
    std::string title;
    std::string x_label;
    std::string y_label;
    bool log_x = false;  ///< decades with 1-2-5 ticks (x must be positive)
    int width = 960;     ///< pixels
    int height = 640;
    std::vector<PlotSeries> series;
};

/// Renders `spec`. Throws ConfigError if there is no finite point, an x is not positive on a log
/// axis, or the image is too small for the margins (under 320 x 240).
RgbImage render_plot(const PlotSpec& spec);

/// Tick positions for an axis over [lo, hi]: "nice" steps (1, 2, 2.5, 5 x 10^k) giving about
/// `target` ticks on a linear axis; 1-2-5 values (or whole decades over long ranges) on a log axis.
std::vector<double> axis_ticks(double lo, double hi, bool log_scale, int target = 6);

/// A tick value as text without trailing zeros ("0.5", "2", "20", "2.5").
std::string format_tick(double value);

/// The study's figure: map memory (MB, log x) against Chamfer-L1 (cm), one line per method
/// through its resolutions in ascending order, points labelled with the resolution. Rows without
/// metrics are left out; throws ConfigError if no row has metrics.
RgbImage plot_memory_vs_chamfer(const std::vector<BenchRow>& rows, int width = 960,
                                int height = 640);

}  // namespace shine
