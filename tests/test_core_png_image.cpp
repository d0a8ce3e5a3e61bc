// RgbImage and its PNG writer (read back with libpng itself), and the raster drawing primitives
// with the built-in 5 x 7 font.
#include <gtest/gtest.h>
#include <png.h>

#include <cctype>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "shine/core/error.hpp"
#include "shine/core/png_image.hpp"
#include "shine/core/raster.hpp"

namespace fs = std::filesystem;
using namespace shine;

namespace {

const fs::path kDir = fs::path(SHINE_TEST_TMP_DIR) / "core_png_image";

fs::path test_path(const std::string& name) {
    fs::create_directories(kDir);
    return kDir / name;
}

/// Reads an 8-bit RGB PNG with libpng's simplified API (independent of the writer's code path).
struct ReadBack {
    int width = 0, height = 0;
    std::vector<std::uint8_t> rgb;
};

ReadBack read_png_rgb(const fs::path& path) {
    png_image image;
    std::memset(&image, 0, sizeof(image));
    image.version = PNG_IMAGE_VERSION;
    EXPECT_TRUE(png_image_begin_read_from_file(&image, path.c_str())) << image.message;
    EXPECT_EQ(image.format & PNG_FORMAT_FLAG_COLOR, PNG_FORMAT_FLAG_COLOR);
    EXPECT_EQ(image.format & PNG_FORMAT_FLAG_ALPHA, 0u) << "written without alpha";
    image.format = PNG_FORMAT_RGB;
    ReadBack out;
    out.width = static_cast<int>(image.width);
    out.height = static_cast<int>(image.height);
    out.rgb.resize(PNG_IMAGE_SIZE(image));
    EXPECT_TRUE(png_image_finish_read(&image, nullptr, out.rgb.data(), 0, nullptr))
        << image.message;
    return out;
}

int count_pixels(const RgbImage& image, Rgb colour) {
    int n = 0;
    for (int y = 0; y < image.height(); ++y) {
        for (int x = 0; x < image.width(); ++x) n += image.at(x, y) == colour;
    }
    return n;
}

constexpr Rgb kRed{200, 10, 20};
constexpr Rgb kWhite{255, 255, 255};

}  // namespace

TEST(RgbImage, RejectsBadSizes) {
    EXPECT_THROW(RgbImage(0, 10), ConfigError);
    EXPECT_THROW(RgbImage(10, -1), ConfigError);
    EXPECT_THROW(RgbImage(RgbImage::kMaxSide + 1, 1), ConfigError);
}

TEST(RgbImage, SetIgnoresPixelsOutsideAndAtThrows) {
    RgbImage image(4, 3, kWhite);
    image.set(-1, 0, kRed);
    image.set(4, 2, kRed);
    image.set(3, 2, kRed);
    EXPECT_EQ(count_pixels(image, kRed), 1);
    EXPECT_EQ(image.at(3, 2), kRed);
    EXPECT_THROW(image.at(4, 0), std::out_of_range);
}

TEST(RgbImage, PngRoundTripGivesSameSizeAndPixels) {
    // Odd sizes and a gradient catch stride and channel-order mistakes.
    RgbImage image(37, 23, kWhite);
    for (int y = 0; y < image.height(); ++y) {
        for (int x = 0; x < image.width(); ++x) {
            image.set(x, y,
                      {static_cast<std::uint8_t>(x * 7), static_cast<std::uint8_t>(y * 11),
                       static_cast<std::uint8_t>((x + y) % 256)});
        }
    }
    const fs::path path = test_path("gradient.png");
    fs::remove(path);
    image.write_png(path);
    ASSERT_TRUE(fs::exists(path));
    const ReadBack back = read_png_rgb(path);
    EXPECT_EQ(back.width, 37);
    EXPECT_EQ(back.height, 23);
    EXPECT_EQ(back.rgb, image.pixels());
    // No temporary file is left beside it.
    for (const auto& entry : fs::directory_iterator(kDir)) {
        EXPECT_EQ(entry.path().filename().string().find(".tmp."), std::string::npos)
            << entry.path();
    }
}

TEST(RgbImage, UnwritablePathThrowsIoErrorNamingIt) {
    const fs::path path = test_path("no_such_dir") / "x.png";
    RgbImage image(2, 2);
    try {
        image.write_png(path);
        FAIL() << "expected IoError";
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("x.png"), std::string::npos) << e.what();
    }
    EXPECT_FALSE(fs::exists(path));
}

TEST(Raster, GlyphsOfTheFont) {
    // 'L': a left column and a full bottom row.
    const auto l = glyph_rows('L');
    for (int row = 0; row < 6; ++row) EXPECT_EQ(l[row], 0x10) << row;
    EXPECT_EQ(l[6], 0x1F);
    // Space is empty; every printable character but space has ink; others get a box.
    for (const auto bits : glyph_rows(' ')) EXPECT_EQ(bits, 0);
    for (char c = 33; c < 127; ++c) {
        int ink = 0;
        for (const auto bits : glyph_rows(c)) {
            ink += bits != 0;
            EXPECT_EQ(bits & ~0x1F, 0) << "glyph '" << c << "' is wider than 5";
        }
        EXPECT_GT(ink, 0) << "glyph '" << c << "' is empty";
    }
    EXPECT_EQ(glyph_rows('\n')[0], 0x1F);
    // Distinct digits and letters (a copy-paste slip would make two the same).
    for (char a = '0'; a <= 'z'; ++a) {
        for (char b = a + 1; b <= 'z'; ++b) {
            if (std::isalnum(a) && std::isalnum(b)) {
                EXPECT_NE(glyph_rows(a), glyph_rows(b)) << a << b;
            }
        }
    }
}

TEST(Raster, TextInksExactlyTheGlyphPixelsScaled) {
    constexpr int kScale = 3;
    RgbImage image(80, 40, kWhite);
    draw_text(image, 5, 4, "E1", kRed, kScale);
    int glyph_ink = 0;
    for (const char c : std::string("E1")) {
        for (const auto bits : glyph_rows(c)) glyph_ink += __builtin_popcount(bits);
    }
    EXPECT_EQ(count_pixels(image, kRed), glyph_ink * kScale * kScale);
    // 'E' starts with a full top row: pixels (5..19, 4..6) are inked, the pixel above is not.
    EXPECT_EQ(image.at(5, 4), kRed);
    EXPECT_EQ(image.at(5 + 5 * kScale - 1, 4 + kScale - 1), kRed);
    EXPECT_EQ(image.at(5, 3), kWhite);
    EXPECT_EQ(text_width("E1", kScale), (2 * kGlyphAdvance - 1) * kScale);
    EXPECT_EQ(text_width("", kScale), 0);
}

TEST(Raster, VerticalTextReadsBottomToTop) {
    RgbImage image(20, 20, kWhite);
    // 'L' (11 pixels) rotated a quarter turn counter-clockwise, bottom-left at (2, 15): its left
    // column becomes the bottom row, its bottom row the right column, reading upwards.
    draw_text_vertical(image, 2, 15, "L", kRed);
    EXPECT_EQ(count_pixels(image, kRed), 11);
    for (int x = 2; x < 2 + kGlyphHeight; ++x) EXPECT_EQ(image.at(x, 15), kRed) << x;
    for (int y = 15 - kGlyphWidth + 1; y <= 15; ++y) EXPECT_EQ(image.at(8, y), kRed) << y;
}

TEST(Raster, LinesRectanglesAndDiscs) {
    RgbImage image(50, 50, kWhite);
    draw_line(image, 2, 3, 40, 3, kRed);
    EXPECT_EQ(count_pixels(image, kRed), 39);
    image.fill(kWhite);
    draw_line(image, 0, 0, 49, 49, kRed);
    EXPECT_EQ(count_pixels(image, kRed), 50);
    for (int i = 0; i < 50; ++i) EXPECT_EQ(image.at(i, i), kRed);
    image.fill(kWhite);
    draw_line(image, 10, 10, 30, 10, kRed, 3);
    EXPECT_EQ(image.at(20, 9), kRed);
    EXPECT_EQ(image.at(20, 11), kRed);
    EXPECT_EQ(image.at(20, 13), kWhite);
    image.fill(kWhite);
    fill_rect(image, 45, 45, 60, 60, kRed);  // clipped at the border
    EXPECT_EQ(count_pixels(image, kRed), 25);
    image.fill(kWhite);
    draw_rect(image, 10, 10, 19, 14, kRed);
    EXPECT_EQ(count_pixels(image, kRed), 2 * 10 + 2 * 3);
    image.fill(kWhite);
    fill_disc(image, 25, 25, 10, kRed);
    const double area = count_pixels(image, kRed);
    constexpr double kDiscArea = 3.14159265358979 * 10 * 10;
    EXPECT_NEAR(area, kDiscArea, 0.05 * kDiscArea);  // pixel count within 5 % of pi r^2
}
