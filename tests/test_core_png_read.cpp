// RgbImage::read_png / parse_png on PNGs written by the minimal encoder below (zlib's compress
// and crc32 only, no libpng), so the reader is checked against files it did not write: every
// colour type, 1- to 16-bit samples, Adam7 interlacing, and damaged files.
#include <gtest/gtest.h>
#include <zlib.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/core/png_image.hpp"

namespace fs = std::filesystem;
using shine::IoError;
using shine::Rgb;
using shine::RgbImage;

namespace {

const fs::path kDir = fs::path(SHINE_TEST_TMP_DIR) / "core_png_read";

constexpr int kGrey = 0, kRgb = 2, kPalette = 3, kGreyAlpha = 4, kRgba = 6;  // PNG colour types

int channels_of(int colour_type) {
    switch (colour_type) {
        case kGrey:
        case kPalette:
            return 1;
        case kGreyAlpha:
            return 2;
        case kRgb:
            return 3;
        default:
            return 4;
    }
}

/// An image to encode: `samples` row-major, channels_of(colour_type) per pixel, each < 2^depth.
struct PngSpec {
    int width = 0, height = 0;
    int bit_depth = 8;
    int colour_type = kRgb;
    bool interlaced = false;
    std::vector<std::uint16_t> samples;
    std::vector<Rgb> palette;  ///< PLTE (colour type 3)
    std::string trns;          ///< the tRNS chunk's data (empty: none)
};

PngSpec make_spec(int width, int height, int bit_depth, int colour_type, bool interlaced = false) {
    PngSpec spec;
    spec.width = width;
    spec.height = height;
    spec.bit_depth = bit_depth;
    spec.colour_type = colour_type;
    spec.interlaced = interlaced;
    return spec;
}

void put_u32(std::string& out, std::uint32_t v) {
    for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<char>(v >> shift));
}

void put_chunk(std::string& out, const char* type, const std::string& data) {
    put_u32(out, static_cast<std::uint32_t>(data.size()));
    const std::string body = std::string(type, 4) + data;
    out += body;
    put_u32(out, static_cast<std::uint32_t>(
                     crc32(0, reinterpret_cast<const Bytef*>(body.data()), body.size())));
}

/// Filter-0 scanlines of the pixels (x0 + i * dx, y0 + j * dy): one Adam7 pass or the image.
void append_scanlines(const PngSpec& spec, int x0, int y0, int dx, int dy, std::string& raw) {
    const int channels = channels_of(spec.colour_type);
    for (int y = y0; y < spec.height; y += dy) {
        if (x0 >= spec.width) return;  // an empty pass has no scanlines at all
        raw.push_back('\0');
        std::uint32_t bits = 0;
        int nbits = 0;
        for (int x = x0; x < spec.width; x += dx) {
            for (int c = 0; c < channels; ++c) {
                const std::uint16_t v =
                    spec.samples[(static_cast<std::size_t>(y) * spec.width + x) * channels + c];
                if (spec.bit_depth == 16) {
                    raw.push_back(static_cast<char>(v >> 8));
                    raw.push_back(static_cast<char>(v & 0xFF));
                    continue;
                }
                bits = (bits << spec.bit_depth) | v;  // packed most significant bits first
                nbits += spec.bit_depth;
                if (nbits == 8) {
                    raw.push_back(static_cast<char>(bits));
                    bits = 0;
                    nbits = 0;
                }
            }
        }
        if (nbits > 0) raw.push_back(static_cast<char>(bits << (8 - nbits)));
    }
}

std::string encode_png(const PngSpec& spec) {
    std::string png = "\x89PNG\r\n\x1a\n";
    std::string ihdr;
    put_u32(ihdr, static_cast<std::uint32_t>(spec.width));
    put_u32(ihdr, static_cast<std::uint32_t>(spec.height));
    ihdr += {static_cast<char>(spec.bit_depth), static_cast<char>(spec.colour_type), 0, 0,
             static_cast<char>(spec.interlaced ? 1 : 0)};
    put_chunk(png, "IHDR", ihdr);
    if (!spec.palette.empty()) {
        std::string plte;
        for (const Rgb& c : spec.palette) {
            plte += {static_cast<char>(c.r), static_cast<char>(c.g), static_cast<char>(c.b)};
        }
        put_chunk(png, "PLTE", plte);
    }
    if (!spec.trns.empty()) put_chunk(png, "tRNS", spec.trns);
    std::string raw;
    if (spec.interlaced) {
        // Adam7: (x0, y0, dx, dy) of the seven passes.
        const int passes[7][4] = {{0, 0, 8, 8}, {4, 0, 8, 8}, {0, 4, 4, 8}, {2, 0, 4, 4},
                                  {0, 2, 2, 4}, {1, 0, 2, 2}, {0, 1, 1, 2}};
        for (const auto& p : passes) append_scanlines(spec, p[0], p[1], p[2], p[3], raw);
    } else {
        append_scanlines(spec, 0, 0, 1, 1, raw);
    }
    uLongf size = compressBound(raw.size());
    std::string idat(size, '\0');
    EXPECT_EQ(compress(reinterpret_cast<Bytef*>(idat.data()), &size,
                       reinterpret_cast<const Bytef*>(raw.data()), raw.size()),
              Z_OK);
    idat.resize(size);
    put_chunk(png, "IDAT", idat);
    put_chunk(png, "IEND", "");
    return png;
}

fs::path write_file(const std::string& name, const std::string& bytes) {
    fs::create_directories(kDir);
    const fs::path path = kDir / name;
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    EXPECT_TRUE(out.good());
    return path;
}

/// Reads `spec` written to a file and checks every pixel against expected(x, y).
template <typename Expected>
void expect_pixels(const PngSpec& spec, const std::string& name, Expected expected) {
    const RgbImage image = RgbImage::read_png(write_file(name, encode_png(spec)));
    ASSERT_EQ(image.width(), spec.width);
    ASSERT_EQ(image.height(), spec.height);
    for (int y = 0; y < spec.height; ++y) {
        for (int x = 0; x < spec.width; ++x) {
            const Rgb want = expected(x, y);
            const Rgb got = image.at(x, y);
            ASSERT_EQ(got, want) << name << " pixel (" << x << ", " << y << "): got " << int(got.r)
                                 << " " << int(got.g) << " " << int(got.b) << ", expected "
                                 << int(want.r) << " " << int(want.g) << " " << int(want.b);
        }
    }
}

/// Deterministic sample values below 2^depth.
std::vector<std::uint16_t> samples(int count, int depth, std::uint32_t seed) {
    std::vector<std::uint16_t> v(count);
    std::uint32_t s = seed;
    for (auto& x : v) {
        s = s * 1664525u + 1013904223u;
        x = static_cast<std::uint16_t>((s >> 8) & ((1u << depth) - 1));
    }
    return v;
}

std::uint8_t scale16(std::uint16_t v) {
    return static_cast<std::uint8_t>(std::lround(v * 255.0 / 65535.0));
}

template <typename F>
void expect_io_error(F&& f, const std::string& name, const std::string& fragment = "") {
    try {
        f();
        ADD_FAILURE() << "expected IoError for " << name;
    } catch (const IoError& e) {
        const std::string message = e.what();
        EXPECT_NE(message.find(name), std::string::npos) << message;
        EXPECT_NE(message.find(fragment), std::string::npos)
            << "missing '" << fragment << "' in: " << message;
    }
}

}  // namespace

TEST(PngRead, Grey8) {
    PngSpec spec = make_spec(5, 3, 8, kGrey);
    spec.samples = samples(15, 8, 1);
    spec.samples[0] = 0;
    spec.samples[1] = 255;
    expect_pixels(spec, "grey8.png", [&](int x, int y) {
        const auto v = static_cast<std::uint8_t>(spec.samples[y * 5 + x]);
        return Rgb{v, v, v};
    });
}

TEST(PngRead, Grey16ScaledWithRounding) {
    PngSpec spec = make_spec(4, 2, 16, kGrey);
    spec.samples = {0, 65535, 0x8080, 0x1234, 0x00FF, 0x7FFF, 0x0080, 0xFF7F};
    expect_pixels(spec, "grey16.png", [&](int x, int y) {
        const std::uint8_t v = scale16(spec.samples[y * 4 + x]);
        return Rgb{v, v, v};
    });
    // Rounded to the nearest v * 255 / 65535, not the high byte: 0x00FF -> 1, 0x8080 -> 128.
    const RgbImage image = RgbImage::read_png(kDir / "grey16.png");
    EXPECT_EQ(image.at(0, 1).r, 1);
    EXPECT_EQ(image.at(1, 1).r, 127);
    EXPECT_EQ(image.at(2, 0).r, 128);
    EXPECT_EQ(image.at(2, 1).r, 0);
}

TEST(PngRead, GreyOneBitExpandsTo0And255) {
    PngSpec spec = make_spec(11, 3, 1, kGrey);  // 11 pixels: a partly filled last byte per row
    spec.samples = samples(33, 1, 2);
    expect_pixels(spec, "grey1.png", [&](int x, int y) {
        const std::uint8_t v = spec.samples[y * 11 + x] ? 255 : 0;
        return Rgb{v, v, v};
    });
}

TEST(PngRead, GreyAlpha8DropsAlpha) {
    PngSpec spec = make_spec(3, 2, 8, kGreyAlpha);
    spec.samples = samples(12, 8, 3);
    spec.samples[1] = 0;  // fully transparent: the grey value is still what is read
    expect_pixels(spec, "grey_alpha8.png", [&](int x, int y) {
        const auto v = static_cast<std::uint8_t>(spec.samples[(y * 3 + x) * 2]);
        return Rgb{v, v, v};
    });
}

TEST(PngRead, Rgb8) {
    PngSpec spec = make_spec(4, 3, 8, kRgb);
    spec.samples = samples(36, 8, 4);
    expect_pixels(spec, "rgb8.png", [&](int x, int y) {
        const std::size_t i = (y * 4 + x) * 3;
        return Rgb{static_cast<std::uint8_t>(spec.samples[i]),
                   static_cast<std::uint8_t>(spec.samples[i + 1]),
                   static_cast<std::uint8_t>(spec.samples[i + 2])};
    });
}

TEST(PngRead, GreyAndRgbTransparencyIgnored) {
    PngSpec grey = make_spec(3, 1, 8, kGrey);
    grey.samples = {7, 8, 9};
    grey.trns = std::string("\0\x08", 2);  // grey 8 transparent
    expect_pixels(grey, "grey_trns.png", [&](int x, int) {
        const auto v = static_cast<std::uint8_t>(grey.samples[x]);
        return Rgb{v, v, v};
    });
    PngSpec rgb = make_spec(2, 1, 8, kRgb);
    rgb.samples = {1, 2, 3, 4, 5, 6};
    rgb.trns = std::string("\0\x01\0\x02\0\x03", 6);  // (1, 2, 3) transparent
    expect_pixels(rgb, "rgb_trns.png", [&](int x, int) {
        return x == 0 ? Rgb{1, 2, 3} : Rgb{4, 5, 6};
    });
}

TEST(PngRead, Rgb16) {
    PngSpec spec = make_spec(3, 2, 16, kRgb);
    spec.samples = samples(18, 16, 5);
    expect_pixels(spec, "rgb16.png", [&](int x, int y) {
        const std::size_t i = (y * 3 + x) * 3;
        return Rgb{scale16(spec.samples[i]), scale16(spec.samples[i + 1]),
                   scale16(spec.samples[i + 2])};
    });
}

TEST(PngRead, Rgba8DropsAlphaWithoutComposing) {
    PngSpec spec = make_spec(4, 2, 8, kRgba);
    spec.samples = samples(32, 8, 6);
    spec.samples[3] = 0;    // pixel (0, 0) fully transparent
    spec.samples[7] = 128;  // pixel (1, 0) half transparent
    expect_pixels(spec, "rgba8.png", [&](int x, int y) {
        const std::size_t i = (y * 4 + x) * 4;
        return Rgb{static_cast<std::uint8_t>(spec.samples[i]),
                   static_cast<std::uint8_t>(spec.samples[i + 1]),
                   static_cast<std::uint8_t>(spec.samples[i + 2])};
    });
}

TEST(PngRead, Rgba16) {
    PngSpec spec = make_spec(2, 2, 16, kRgba);
    spec.samples = samples(16, 16, 7);
    expect_pixels(spec, "rgba16.png", [&](int x, int y) {
        const std::size_t i = (y * 2 + x) * 4;
        return Rgb{scale16(spec.samples[i]), scale16(spec.samples[i + 1]),
                   scale16(spec.samples[i + 2])};
    });
}

TEST(PngRead, Palette8WithTransparencyIgnored) {
    PngSpec spec = make_spec(5, 2, 8, kPalette);
    spec.palette = {{10, 20, 30}, {255, 0, 0}, {0, 255, 0}, {1, 2, 3}};
    spec.trns = {0, static_cast<char>(128)};  // entries 0 and 1 (partly) transparent
    spec.samples = {0, 1, 2, 3, 0, 3, 2, 1, 0, 1};
    expect_pixels(spec, "palette8.png",
                  [&](int x, int y) { return spec.palette[spec.samples[y * 5 + x]]; });
}

TEST(PngRead, Palette4) {
    PngSpec spec = make_spec(7, 2, 4, kPalette);
    for (int i = 0; i < 16; ++i) {
        spec.palette.push_back({static_cast<std::uint8_t>(i * 16), static_cast<std::uint8_t>(i),
                                static_cast<std::uint8_t>(255 - i)});
    }
    spec.samples = samples(14, 4, 8);
    expect_pixels(spec, "palette4.png",
                  [&](int x, int y) { return spec.palette[spec.samples[y * 7 + x]]; });
}

TEST(PngRead, InterlacedMatchesTheSamePixelsNonInterlaced) {
    // 11 x 9: every Adam7 pass has pixels, and the passes' rows have partial bytes at 2 bits.
    for (const int depth : {2, 8, 16}) {
        for (const int colour_type : {kGrey, kRgb}) {
            if (depth == 2 && colour_type == kRgb) continue;  // not a valid PNG combination
            PngSpec spec = make_spec(11, 9, depth, colour_type, true);
            spec.samples = samples(11 * 9 * channels_of(colour_type), depth, 9);
            const std::string name =
                "interlaced_" + std::to_string(depth) + "_" + std::to_string(colour_type) + ".png";
            const RgbImage interlaced = RgbImage::read_png(write_file(name, encode_png(spec)));
            spec.interlaced = false;
            const RgbImage plain = RgbImage::parse_png(encode_png(spec), "plain");
            EXPECT_EQ(interlaced.width(), 11);
            EXPECT_EQ(interlaced.pixels(), plain.pixels()) << name;
        }
    }
    // And against the values themselves, for 8-bit RGB.
    PngSpec spec = make_spec(11, 9, 8, kRgb, true);
    spec.samples = samples(11 * 9 * 3, 8, 10);
    expect_pixels(spec, "interlaced_rgb8.png", [&](int x, int y) {
        const std::size_t i = (y * 11 + x) * 3;
        return Rgb{static_cast<std::uint8_t>(spec.samples[i]),
                   static_cast<std::uint8_t>(spec.samples[i + 1]),
                   static_cast<std::uint8_t>(spec.samples[i + 2])};
    });
}

TEST(PngRead, ReadsWhatWritePngWrote) {
    RgbImage image(6, 4, {1, 2, 3});
    image.set(5, 3, {250, 128, 7});
    const fs::path path = kDir / "round_trip.png";
    fs::create_directories(kDir);
    image.write_png(path);
    EXPECT_EQ(RgbImage::read_png(path).pixels(), image.pixels());
}

TEST(PngRead, EveryTruncationIsAnIoErrorNamingTheFile) {
    PngSpec spec = make_spec(6, 5, 8, kRgb);
    spec.samples = samples(90, 8, 11);
    const std::string png = encode_png(spec);
    for (std::size_t size = 0; size < png.size(); ++size) {
        const std::string name = "truncated_" + std::to_string(size) + ".png";
        expect_io_error([&] { RgbImage::read_png(write_file(name, png.substr(0, size))); }, name);
    }
    expect_io_error([&] { RgbImage::parse_png(png.substr(0, png.size() - 20), "cut.png"); },
                    "cut.png", "truncated");
}

TEST(PngRead, CorruptFilesAreIoErrorsWithLibpngsMessage) {
    PngSpec spec = make_spec(6, 5, 8, kRgb);
    spec.samples = samples(90, 8, 12);
    const std::string png = encode_png(spec);
    const std::size_t idat_data = png.find("IDAT") + 4;

    // A flipped byte in IHDR: the chunk's CRC no longer matches.
    std::string flipped = png;
    flipped[8 + 8 + 3] ^= 0x01;
    expect_io_error([&] { RgbImage::read_png(write_file("bad_crc.png", flipped)); }, "bad_crc.png",
                    "CRC error");

    // A flipped byte in the compressed data: inflate or the CRC fails, whichever comes first.
    std::string flipped_idat = png;
    flipped_idat[idat_data + 5] ^= 0x40;
    expect_io_error([&] { RgbImage::read_png(write_file("bad_idat.png", flipped_idat)); },
                    "bad_idat.png", "libpng:");

    // A broken zlib header under a correct CRC: libpng's inflate fails.
    std::string bad_zlib = png;
    bad_zlib[idat_data] = 0x00;
    bad_zlib[idat_data + 1] = 0x00;
    const std::uint32_t length = static_cast<std::uint32_t>(png.find("IEND") - 12 - idat_data);
    const std::string body = bad_zlib.substr(idat_data - 4, 4 + length);
    std::string crc;
    put_u32(crc, static_cast<std::uint32_t>(
                     crc32(0, reinterpret_cast<const Bytef*>(body.data()), body.size())));
    bad_zlib.replace(idat_data + length, 4, crc);
    expect_io_error([&] { RgbImage::read_png(write_file("bad_zlib.png", bad_zlib)); },
                    "bad_zlib.png", "libpng:");

    // An invalid colour type / depth pair in IHDR.
    PngSpec bad_header = spec;
    bad_header.bit_depth = 4;  // RGB must be 8 or 16 bits
    std::string bad_ihdr = encode_png(bad_header);
    expect_io_error([&] { RgbImage::read_png(write_file("bad_ihdr.png", bad_ihdr)); },
                    "bad_ihdr.png", "libpng:");

    expect_io_error([&] { RgbImage::read_png(write_file("text.png", "width: 640\n")); }, "text.png",
                    "not a PNG");
    expect_io_error([&] { RgbImage::read_png(kDir / "missing.png"); }, "missing.png",
                    "does not exist");
    expect_io_error([&] { RgbImage::read_png(kDir); }, kDir.string(), "directory");
}

TEST(PngRead, SizesBeyondTheLimitOrTheDataAreRejectedBeforeAllocating) {
    // 30000 x 30000 RGB (2.7 GB decoded) claimed by a file of a few bytes of pixel data.
    PngSpec small = make_spec(2, 1, 8, kRgb);
    small.samples = {1, 2, 3, 4, 5, 6};
    std::string huge = encode_png(small);
    std::string ihdr;
    put_u32(ihdr, 30000);
    put_u32(ihdr, 30000);
    ihdr += {8, kRgb, 0, 0, 0};
    std::string chunk;
    put_chunk(chunk, "IHDR", ihdr);
    huge.replace(8, chunk.size(), chunk);
    expect_io_error([&] { RgbImage::parse_png(huge, "huge.png"); }, "huge.png", "30000 x 30000");

    PngSpec wide = make_spec(RgbImage::kMaxSide + 1, 1, 1, kGrey);
    wide.samples.assign(wide.width, 0);
    expect_io_error([&] { RgbImage::parse_png(encode_png(wide), "wide.png"); }, "wide.png",
                    "libpng:");
}

TEST(PngRead, RealKitti360CameraImage) {
    const fs::path path = "/work/shared/data/kitti360_drive/image_00/000000.png";
    if (!fs::exists(path)) GTEST_SKIP() << path << " is not on this machine";
    const RgbImage image = RgbImage::read_png(path);
    EXPECT_EQ(image.width(), 1408);
    EXPECT_EQ(image.height(), 376);
    // A street scene: many distinct colours, not a constant or grey image.
    int coloured = 0;
    for (int y = 0; y < image.height(); y += 8) {
        for (int x = 0; x < image.width(); x += 8) {
            const Rgb c = image.at(x, y);
            if (c.r != c.g || c.g != c.b) ++coloured;
        }
    }
    EXPECT_GT(coloured, 1000);
}
