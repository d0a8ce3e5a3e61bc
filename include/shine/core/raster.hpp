// Drawing on an RgbImage: thick lines, discs, rectangles and text in a built-in 5 x 7 bitmap font
// (printable ASCII), scaled by whole pixels. No anti-aliasing: enough for plots and labels.
// Everything clips at the image border.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "shine/core/png_image.hpp"

namespace shine {

/// Glyph cell of the bitmap font at scale 1, in pixels; characters advance by kGlyphAdvance.
constexpr int kGlyphWidth = 5;
constexpr int kGlyphHeight = 7;
constexpr int kGlyphAdvance = 6;

/// Rows of the 5 x 7 glyph of `c`, top row first; bit 4 is the leftmost pixel. Characters outside
/// printable ASCII (32..126) get a hollow box.
std::array<std::uint8_t, kGlyphHeight> glyph_rows(char c);

/// Width and height in pixels of `text` drawn at `scale` (one line, no trailing gap).
int text_width(const std::string& text, int scale = 1);
inline int text_height(int scale = 1) { return kGlyphHeight * scale; }

/// Draws `text` with its top-left corner at (x, y), each font pixel a `scale` x `scale` block.
void draw_text(RgbImage& image, int x, int y, const std::string& text, Rgb colour, int scale = 1);

/// Draws `text` rotated a quarter turn counter-clockwise (reading bottom to top, as a y-axis
/// label), with the bottom-left corner of the rotated block at (x, y).
void draw_text_vertical(RgbImage& image, int x, int y, const std::string& text, Rgb colour,
                        int scale = 1);

/// Fills the rectangle [x0, x1] x [y0, y1] (inclusive, any corner order).
void fill_rect(RgbImage& image, int x0, int y0, int x1, int y1, Rgb colour);

/// Draws the one-pixel outline of the rectangle [x0, x1] x [y0, y1].
void draw_rect(RgbImage& image, int x0, int y0, int x1, int y1, Rgb colour);

/// Fills the disc of `radius` pixels around (cx, cy).
void fill_disc(RgbImage& image, double cx, double cy, double radius, Rgb colour);

/// Draws a line from (x0, y0) to (x1, y1), `thickness` pixels wide (a disc swept along it; a
/// thickness of 1 gives a plain Bresenham line).
void draw_line(RgbImage& image, double x0, double y0, double x1, double y1, Rgb colour,
               int thickness = 1);

}  // namespace shine
