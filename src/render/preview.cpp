#include "shine/render/preview.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "shine/core/raster.hpp"

namespace shine {
namespace {

constexpr int kLegendHeightPx = 44;
constexpr Rgb kLegendBackground = {255, 255, 255};
constexpr Rgb kText = {0, 0, 0};

Rgb lerp(Rgb a, Rgb b, double t) {
    const auto mix = [t](std::uint8_t x, std::uint8_t y) {
        return static_cast<std::uint8_t>(std::lround(x + (double(y) - double(x)) * t));
    };
    return {mix(a.r, b.r), mix(a.g, b.g), mix(a.b, b.b)};
}

/// Piecewise-linear map through `stops` (evenly spaced over [0, 1]).
template <std::size_t N>
Rgb ramp(const Rgb (&stops)[N], double t) {
    t = std::clamp(t, 0.0, 1.0) * double(N - 1);
    const std::size_t k = std::min<std::size_t>(N - 2, static_cast<std::size_t>(t));
    return lerp(stops[k], stops[k + 1], t - double(k));
}

constexpr Rgb kSequential[] = {
    {48, 18, 59}, {40, 110, 190}, {30, 170, 160}, {140, 210, 80}, {250, 230, 40}};
constexpr Rgb kDiverging[] = {
    {30, 60, 170}, {120, 160, 230}, {255, 255, 255}, {235, 130, 100}, {170, 20, 30}};

std::string number(double v) {
    char text[32];
    std::snprintf(text, sizeof(text), std::abs(v) >= 100 ? "%.0f" : "%.2f", v);
    return text;
}

struct Canvas {
    int scale_x, scale_y, width_px, height_px;
};

Canvas canvas_for(int width, int height, const PreviewLayout& layout) {
    Canvas c;
    c.scale_x = std::max(1, std::min(layout.max_width_px, 512) / width);
    c.scale_y = std::max(1, (layout.min_height_px + height - 1) / height);
    c.width_px = std::max(width * c.scale_x, 320);
    c.height_px = height * c.scale_y + kLegendHeightPx;
    return c;
}

/// Fills the image area from a per-pixel colour function.
template <typename ColourOf>
void paint(RgbImage& image, const Canvas& c, int width, int height, ColourOf colour_of) {
    for (int y = 0; y < height; ++y) {
        for (int x = 0; x < width; ++x) {
            const Rgb colour = colour_of(std::size_t(y) * width + x);
            fill_rect(image, x * c.scale_x, y * c.scale_y, (x + 1) * c.scale_x - 1,
                      (y + 1) * c.scale_y - 1, colour);
        }
    }
}

}  // namespace

Rgb scale_colour(double value, const ColourScale& scale) {
    if (std::isnan(value)) return {0, 0, 0};
    const double span = scale.max - scale.min;
    const double t = span > 0.0 ? (value - scale.min) / span : 0.5;
    return scale.diverging ? ramp(kDiverging, t) : ramp(kSequential, t);
}

double finite_quantile(const std::vector<float>& values, double q, double fallback) {
    std::vector<float> finite;
    for (const float v : values) {
        if (std::isfinite(v)) finite.push_back(v);
    }
    if (finite.empty()) return fallback;
    const std::size_t k = std::min(
        finite.size() - 1, static_cast<std::size_t>(std::clamp(q, 0.0, 1.0) * finite.size()));
    std::nth_element(finite.begin(), finite.begin() + k, finite.end());
    return finite[k];
}

RgbImage preview_scalar(const std::vector<float>& values, int width, int height,
                        const ColourScale& scale, const std::string& title,
                        const PreviewLayout& layout, const std::vector<float>& other) {
    const Canvas c = canvas_for(width, height, layout);
    RgbImage image(c.width_px, c.height_px, kLegendBackground);
    paint(image, c, width, height, [&](std::size_t i) {
        if (std::isnan(values[i]) && !other.empty() && std::isfinite(other[i])) {
            return layout.missing_colour;
        }
        if (std::isnan(values[i])) return layout.nan_colour;
        return scale_colour(values[i], scale);
    });
    if (layout.zero_level) {
        for (int y = 0; y < height; ++y) {
            for (int x = 0; x < width; ++x) {
                const float v = values[std::size_t(y) * width + x];
                const auto crosses = [&](int x2, int y2) {
                    if (x2 >= width || y2 >= height) return false;
                    const float w = values[std::size_t(y2) * width + x2];
                    return std::isfinite(v) && std::isfinite(w) && ((v < 0) != (w < 0));
                };
                if (crosses(x + 1, y) || crosses(x, y + 1)) {
                    fill_rect(image, x * c.scale_x, y * c.scale_y, (x + 1) * c.scale_x - 1,
                              (y + 1) * c.scale_y - 1, {0, 0, 0});
                }
            }
        }
    }
    // Legend: title, then the colour bar between its end values.
    const int top = height * c.scale_y + 4;
    draw_text(image, 4, top, title, kText);
    const std::string lo = number(scale.min) + " " + scale.unit;
    const std::string hi = number(scale.max) + " " + scale.unit;
    const int bar_x0 = 8 + text_width(lo);
    const int bar_x1 = c.width_px - 8 - text_width(hi);
    const int bar_y0 = top + 14, bar_y1 = top + 30;
    draw_text(image, 4, bar_y0 + 5, lo, kText);
    draw_text(image, bar_x1 + 4, bar_y0 + 5, hi, kText);
    for (int x = bar_x0; x < bar_x1; ++x) {
        const double t = double(x - bar_x0) / std::max(1, bar_x1 - bar_x0 - 1);
        fill_rect(image, x, bar_y0, x, bar_y1,
                  scale_colour(scale.min + t * (scale.max - scale.min), scale));
    }
    draw_rect(image, bar_x0 - 1, bar_y0 - 1, bar_x1, bar_y1 + 1, kText);
    return image;
}

RgbImage preview_normals(const std::vector<float>& nx, const std::vector<float>& ny,
                         const std::vector<float>& nz, int width, int height,
                         const std::string& title, const PreviewLayout& layout) {
    const Canvas c = canvas_for(width, height, layout);
    RgbImage image(c.width_px, c.height_px, kLegendBackground);
    const auto channel = [](float v) {
        return static_cast<std::uint8_t>(std::lround(std::clamp((v + 1.0) * 127.5, 0.0, 255.0)));
    };
    paint(image, c, width, height, [&](std::size_t i) {
        if (std::isnan(nx[i])) return Rgb{0, 0, 0};
        return Rgb{channel(nx[i]), channel(ny[i]), channel(nz[i])};
    });
    const int top = height * c.scale_y + 4;
    draw_text(image, 4, top, title, kText);
    draw_text(image, 4, top + 18, "world normal: x red, y green, z blue; black: no surface", kText);
    return image;
}

}  // namespace shine
