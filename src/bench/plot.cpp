#include "shine/bench/plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "shine/core/error.hpp"
#include "shine/core/raster.hpp"

namespace shine {
namespace {

constexpr Rgb kInk{30, 30, 30};
constexpr Rgb kGrid{225, 225, 225};
constexpr Rgb kWhite{255, 255, 255};
constexpr int kTextScale = 2;      // 5 x 7 glyphs drawn as 10 x 14 pixels
constexpr int kTickLength = 6;     // pixels outside the frame
constexpr int kLineThickness = 3;  // series lines
constexpr double kMarkerRadius = 6.0;
constexpr int kMinWidth = 320, kMinHeight = 240;

/// Maps data coordinates to pixels inside the frame [left, right] x [top, bottom].
struct Axes {
    int left, right, top, bottom;
    bool log_x;
    double x_lo, x_hi;  // in axis units (log10 of x on a log axis)
    double y_lo, y_hi;

    double axis_x(double x) const { return log_x ? std::log10(x) : x; }
    double px(double x) const { return left + (axis_x(x) - x_lo) / (x_hi - x_lo) * (right - left); }
    double py(double y) const { return bottom - (y - y_lo) / (y_hi - y_lo) * (bottom - top); }
};

double nice_step(double raw) {
    const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
    for (const double m : {1.0, 2.0, 2.5, 5.0, 10.0}) {
        if (m * magnitude >= raw * (1 - 1e-9)) return m * magnitude;
    }
    return 10.0 * magnitude;
}

void draw_marker(RgbImage& image, double x, double y, MarkerShape shape, Rgb colour) {
    const double r = kMarkerRadius;
    if (shape == MarkerShape::kDisc) {
        fill_disc(image, x, y, r + 1.5, kWhite);
        fill_disc(image, x, y, r, colour);
    } else {
        const int ix = static_cast<int>(std::lround(x)), iy = static_cast<int>(std::lround(y));
        const int h = static_cast<int>(r) - 1;
        fill_rect(image, ix - h - 2, iy - h - 2, ix + h + 2, iy + h + 2, kWhite);
        fill_rect(image, ix - h, iy - h, ix + h, iy + h, colour);
    }
}

}  // namespace

std::vector<double> axis_ticks(double lo, double hi, bool log_scale, int target) {
    std::vector<double> ticks;
    if (!(hi > lo) || !std::isfinite(lo) || !std::isfinite(hi)) return ticks;
    if (!log_scale) {
        const double step = nice_step((hi - lo) / std::max(target, 1));
        for (double k = std::ceil(lo / step - 1e-9); k * step <= hi + step * 1e-9; k += 1.0) {
            const double v = k * step;
            ticks.push_back(std::abs(v) < step * 1e-9 ? 0.0 : v);
        }
        return ticks;
    }
    if (!(lo > 0.0)) return ticks;
    const double decades = std::log10(hi / lo);
    std::vector<double> mantissas = {1.0, 2.0, 5.0};
    if (decades > 4.0) mantissas = {1.0};
    if (decades < 1.0) mantissas = {1.0, 1.5, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0};
    for (int d = static_cast<int>(std::floor(std::log10(lo))) - 1;
         d <= static_cast<int>(std::ceil(std::log10(hi))); ++d) {
        for (const double m : mantissas) {
            // Rounded to 12 significant digits so 0.1 * 2 prints as 0.2.
            const double v = std::stod(std::to_string(m) + "e" + std::to_string(d));
            if (v >= lo * (1 - 1e-12) && v <= hi * (1 + 1e-12)) ticks.push_back(v);
        }
    }
    return ticks;
}

std::string format_tick(double value) {
    char buffer[32];
    std::snprintf(buffer, sizeof(buffer), "%.6g", value);
    return buffer;
}

RgbImage render_plot(const PlotSpec& spec) {
    if (spec.width < kMinWidth || spec.height < kMinHeight) {
        throw ConfigError("plot size " + std::to_string(spec.width) + " x " +
                          std::to_string(spec.height) + " is too small (at least " +
                          std::to_string(kMinWidth) + " x " + std::to_string(kMinHeight) + ")");
    }
    // Data range.
    double x_min = std::numeric_limits<double>::infinity(), x_max = -x_min;
    double y_min = x_min, y_max = -x_min;
    std::size_t points = 0;
    for (const PlotSeries& s : spec.series) {
        for (const PlotPoint& p : s.points) {
            if (!std::isfinite(p.x) || !std::isfinite(p.y)) continue;
            if (spec.log_x && !(p.x > 0.0)) {
                throw ConfigError("plot '" + spec.title + "': x = " + format_tick(p.x) +
                                  " of series '" + s.name + "' cannot go on a log axis");
            }
            x_min = std::min(x_min, p.x);
            x_max = std::max(x_max, p.x);
            y_min = std::min(y_min, p.y);
            y_max = std::max(y_max, p.y);
            ++points;
        }
    }
    if (points == 0) throw ConfigError("plot '" + spec.title + "' has no finite point to draw");

    Axes axes{};
    axes.log_x = spec.log_x;
    double ax_lo = axes.axis_x(x_min), ax_hi = axes.axis_x(x_max);
    if (ax_hi - ax_lo < 1e-9) {
        const double half = spec.log_x ? 0.5 : std::max(std::abs(ax_lo) * 0.1, 1.0);
        ax_lo -= half;
        ax_hi += half;
    }
    const double x_pad = 0.08 * (ax_hi - ax_lo);
    axes.x_lo = ax_lo - x_pad;
    axes.x_hi = ax_hi + x_pad;
    if (y_max - y_min < 1e-12) {
        const double half = std::max(std::abs(y_min) * 0.1, 1.0);
        y_min -= half;
        y_max += half;
    }
    const double y_pad = 0.1 * (y_max - y_min);
    axes.y_lo = y_min - y_pad;
    axes.y_hi = y_max + y_pad;
    if (y_min >= 0.0) axes.y_lo = std::max(axes.y_lo, 0.0);

    const std::vector<double> y_ticks = axis_ticks(axes.y_lo, axes.y_hi, false);
    const double x_tick_lo = spec.log_x ? std::pow(10.0, axes.x_lo) : axes.x_lo;
    const double x_tick_hi = spec.log_x ? std::pow(10.0, axes.x_hi) : axes.x_hi;
    const std::vector<double> x_ticks = axis_ticks(x_tick_lo, x_tick_hi, spec.log_x);

    // Layout: title on top, y label and tick labels on the left, x tick labels and label below.
    const int glyph_h = text_height(kTextScale);
    int y_tick_width = 0;
    for (const double t : y_ticks) {
        y_tick_width = std::max(y_tick_width, text_width(format_tick(t), kTextScale));
    }
    axes.left = 12 + glyph_h + 14 + y_tick_width + kTickLength + 6;
    axes.right = spec.width - 28;
    std::vector<const PlotSeries*> named;  // series with a legend entry
    for (const PlotSeries& s : spec.series) {
        if (!s.name.empty() && !s.points.empty()) named.push_back(&s);
    }
    const int legend_y = spec.title.empty() ? 16 : 20 + glyph_h + 14;
    axes.top = named.empty() ? legend_y + 4 : legend_y + glyph_h + 16;
    axes.bottom = spec.height - (kTickLength + 8 + glyph_h + 16 + glyph_h + 14);

    RgbImage image(spec.width, spec.height, kWhite);

    // Grid and ticks.
    for (const double t : x_ticks) {
        const int x = static_cast<int>(std::lround(axes.px(t)));
        if (x < axes.left || x > axes.right) continue;
        fill_rect(image, x, axes.top, x, axes.bottom, kGrid);
    }
    for (const double t : y_ticks) {
        const int y = static_cast<int>(std::lround(axes.py(t)));
        if (y < axes.top || y > axes.bottom) continue;
        fill_rect(image, axes.left, y, axes.right, y, kGrid);
    }
    draw_rect(image, axes.left, axes.top, axes.right, axes.bottom, kInk);
    int last_label_right = std::numeric_limits<int>::min();
    for (const double t : x_ticks) {
        const int x = static_cast<int>(std::lround(axes.px(t)));
        if (x < axes.left || x > axes.right) continue;
        fill_rect(image, x, axes.bottom, x, axes.bottom + kTickLength, kInk);
        const std::string label = format_tick(t);
        const int w = text_width(label, kTextScale);
        if (x - w / 2 <= last_label_right + 8) continue;  // no overlapping tick labels
        draw_text(image, x - w / 2, axes.bottom + kTickLength + 6, label, kInk, kTextScale);
        last_label_right = x - w / 2 + w;
    }
    for (const double t : y_ticks) {
        const int y = static_cast<int>(std::lround(axes.py(t)));
        if (y < axes.top || y > axes.bottom) continue;
        fill_rect(image, axes.left - kTickLength, y, axes.left, y, kInk);
        const std::string label = format_tick(t);
        draw_text(image, axes.left - kTickLength - 6 - text_width(label, kTextScale),
                  y - glyph_h / 2, label, kInk, kTextScale);
    }

    // Title and axis labels.
    if (!spec.title.empty()) {
        draw_text(image, (spec.width - text_width(spec.title, kTextScale)) / 2, 20, spec.title,
                  kInk, kTextScale);
    }
    draw_text(image, (axes.left + axes.right - text_width(spec.x_label, kTextScale)) / 2,
              spec.height - 14 - glyph_h, spec.x_label, kInk, kTextScale);
    draw_text_vertical(image, 12,
                       (axes.top + axes.bottom + text_width(spec.y_label, kTextScale)) / 2,
                       spec.y_label, kInk, kTextScale);

    // Series: lines, then markers on top, then point labels.
    for (const PlotSeries& s : spec.series) {
        const PlotPoint* previous = nullptr;
        for (const PlotPoint& p : s.points) {
            if (!std::isfinite(p.x) || !std::isfinite(p.y)) continue;
            if (previous) {
                draw_line(image, axes.px(previous->x), axes.py(previous->y), axes.px(p.x),
                          axes.py(p.y), s.colour, kLineThickness);
            }
            previous = &p;
        }
    }
    for (const PlotSeries& s : spec.series) {
        for (const PlotPoint& p : s.points) {
            if (!std::isfinite(p.x) || !std::isfinite(p.y)) continue;
            draw_marker(image, axes.px(p.x), axes.py(p.y), s.marker, s.colour);
        }
    }
    for (const PlotSeries& s : spec.series) {
        for (const PlotPoint& p : s.points) {
            if (p.label.empty() || !std::isfinite(p.x) || !std::isfinite(p.y)) continue;
            const int x = static_cast<int>(std::lround(axes.px(p.x)));
            const int y = static_cast<int>(std::lround(axes.py(p.y)));
            const int w = text_width(p.label, kTextScale);
            // Right of the marker and a little above; mirrored where the frame would cut it.
            int tx = x + 10, ty = y - glyph_h - 6;
            if (tx + w > axes.right - 2) tx = x - 10 - w;
            if (ty < axes.top + 2) ty = y + 8;
            draw_text(image, tx, ty, p.label, s.colour, kTextScale);
        }
    }

    // Legend: one row between the title and the frame, centred on the image, so it never hides
    // data.
    if (!named.empty()) {
        constexpr int kSample = 44, kGap = 10, kEntryGap = 36;
        int total = 0;
        for (const PlotSeries* s : named) {
            total += (total ? kEntryGap : 0) + kSample + kGap + text_width(s->name, kTextScale);
        }
        int x = std::max(8, (spec.width - total) / 2);
        const int mid = legend_y + glyph_h / 2;
        for (const PlotSeries* s : named) {
            draw_line(image, x, mid, x + kSample, mid, s->colour, kLineThickness);
            draw_marker(image, x + kSample / 2.0, mid, s->marker, s->colour);
            draw_text(image, x + kSample + kGap, legend_y, s->name, kInk, kTextScale);
            x += kSample + kGap + text_width(s->name, kTextScale) + kEntryGap;
        }
    }
    return image;
}

RgbImage plot_memory_vs_chamfer(const std::vector<BenchRow>& rows, int width, int height) {
    PlotSpec spec;
    spec.title = "Map memory vs. Chamfer-L1";
    spec.x_label = "map memory (MB, log scale)";
    spec.y_label = "Chamfer-L1 (cm)";
    spec.log_x = true;
    spec.width = width;
    spec.height = height;
    PlotSeries shine{"ShineVDB (leaf size)", {214, 39, 40}, MarkerShape::kDisc, {}};
    PlotSeries tsdf{"TSDF, VDBFusion (voxel)", {31, 119, 180}, MarkerShape::kSquare, {}};
    PlotSeries incremental{
        "ShineVDB incremental (leaf size)", {255, 127, 14}, MarkerShape::kDisc, {}};
    std::vector<const BenchRow*> sorted;
    for (const BenchRow& row : rows) {
        if (row.metrics) sorted.push_back(&row);
    }
    if (sorted.empty()) {
        throw ConfigError("memory vs. Chamfer-L1 plot: no evaluated run (is there a reference?)");
    }
    std::sort(sorted.begin(), sorted.end(),
              [](const BenchRow* a, const BenchRow* b) { return a->size_m < b->size_m; });
    for (const BenchRow* row : sorted) {
        PlotSeries& series = row->method == BenchMethod::kShineVdb ? shine
                             : row->method == BenchMethod::kTsdf   ? tsdf
                                                                   : incremental;
        series.points.push_back({static_cast<double>(row->map_bytes) / 1e6,
                                 row->metrics->chamfer_l1_m * 100.0,
                                 format_size_m(row->size_m) + " m"});
    }
    for (PlotSeries* s : {&shine, &tsdf, &incremental}) {
        if (!s->points.empty()) spec.series.push_back(*s);
    }
    return render_plot(spec);
}

}  // namespace shine
