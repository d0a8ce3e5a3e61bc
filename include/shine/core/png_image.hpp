// An 8-bit RGB raster image in memory, written as PNG (libpng) under a temporary name and renamed,
// so a failed or interrupted write never leaves a truncated image. Used for plots (shine bench)
// and pictures; drawing primitives live in raster.hpp.
//
// Reading (camera images, io/camera_rig.hpp) takes any PNG and keeps the stored values: every bit
// depth, colour type and interlacing is converted to 8-bit RGB (16 bits rounded to v * 255 /
// 65535, grey copied to r = g = b, a palette looked up), alpha and tRNS transparency are dropped
// rather than composed onto a background, and gAMA / sRGB / iCCP chunks are not applied. libpng's
// errors longjmp only across two small functions that own nothing (png_image.cpp); every buffer
// is owned outside them, so a corrupt file ends in an IoError, never a leak.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string_view>
#include <vector>

namespace shine {

/// One 8-bit sRGB colour.
struct Rgb {
    std::uint8_t r = 0, g = 0, b = 0;

    friend bool operator==(const Rgb& a, const Rgb& b) {
        return a.r == b.r && a.g == b.g && a.b == b.b;
    }
    friend bool operator!=(const Rgb& a, const Rgb& b) { return !(a == b); }
};

/// Row-major RGB image, origin at the top-left pixel, x to the right, y down.
class RgbImage {
  public:
    /// Largest width or height accepted (keeps width * height * 3 far from overflow).
    static constexpr int kMaxSide = 1 << 15;

    /// A `width` x `height` image filled with `background`. Throws ConfigError if a side is not
    /// in [1, kMaxSide].
    RgbImage(int width, int height, Rgb background = {255, 255, 255});

    int width() const { return width_; }
    int height() const { return height_; }
    bool contains(int x, int y) const { return x >= 0 && y >= 0 && x < width_ && y < height_; }

    /// Pixel (x, y); throws std::out_of_range outside the image.
    Rgb at(int x, int y) const;
    /// Sets pixel (x, y); pixels outside the image are ignored, so drawing code clips by it.
    void set(int x, int y, Rgb colour) {
        if (!contains(x, y)) return;
        std::uint8_t* p = &pixels_[(static_cast<std::size_t>(y) * width_ + x) * 3];
        p[0] = colour.r;
        p[1] = colour.g;
        p[2] = colour.b;
    }
    void fill(Rgb colour);

    /// The pixels as width * height * 3 bytes, row by row.
    const std::vector<std::uint8_t>& pixels() const { return pixels_; }

    /// Writes the image as an 8-bit RGB PNG, atomically (temporary file + rename). Throws IoError
    /// naming `path` and libpng's message if the file cannot be written.
    void write_png(const std::filesystem::path& path) const;

    /// Reads a PNG file as 8-bit RGB (any bit depth, grey, grey + alpha, RGB, RGBA, palette,
    /// interlaced; conversions above). Throws IoError naming `path` if it is missing or
    /// unreadable, and IoError naming it with libpng's message if it is not a PNG, truncated or
    /// corrupt, or larger than kMaxSide.
    static RgbImage read_png(const std::filesystem::path& path);

    /// read_png on bytes already in memory; `source` names them in messages.
    static RgbImage parse_png(std::string_view data, const std::filesystem::path& source);

  private:
    int width_;
    int height_;
    std::vector<std::uint8_t> pixels_;
};

}  // namespace shine
