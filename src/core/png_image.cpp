#include "shine/core/png_image.hpp"

#include <png.h>

#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <stdexcept>
#include <string>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"

namespace shine {

namespace png_image_internal {
namespace {

/// What libpng reads from, and where its error handler leaves the message before it longjmps.
struct PngReadContext {
    const unsigned char* data = nullptr;
    std::size_t size = 0;
    std::size_t offset = 0;
    char message[256] = {};
};

void png_read_from_context(png_structp png, png_bytep out, png_size_t length) {
    auto* context = static_cast<PngReadContext*>(png_get_io_ptr(png));
    if (length > context->size - context->offset) {
        png_error(png, "unexpected end of file (the file is truncated)");
    }
    std::memcpy(out, context->data + context->offset, length);
    context->offset += length;
}

void png_on_error(png_structp png, png_const_charp message) {
    auto* context = static_cast<PngReadContext*>(png_get_error_ptr(png));
    std::snprintf(context->message, sizeof(context->message), "%s", message);
    png_longjmp(png, 1);
}

// Warnings (an unknown sRGB profile, a bad CRC in an ancillary chunk) do not change the pixels.
void png_on_warning(png_structp, png_const_charp) {}

/// The header of a PNG being read, after the conversion to 8-bit RGB was set up.
struct PngHeader {
    png_uint_32 width = 0, height = 0;
    int bit_depth = 0;
    int channels = 0;              ///< as stored (1 for a palette)
    png_size_t rgb_row_bytes = 0;  ///< after the conversion
};

// The two functions below are the only frames a libpng error longjmps across: C-style, they own
// nothing with a destructor and leave their results through pointers, so skipping them is safe.

/// Reads the header and sets up the conversion to 8-bit RGB; false after a libpng error.
bool png_read_header_rgb8(png_structp png, png_infop info, PngHeader* header) {
    if (setjmp(png_jmpbuf(png))) return false;
    png_read_info(png, info);
    header->width = png_get_image_width(png, info);
    header->height = png_get_image_height(png, info);
    header->bit_depth = png_get_bit_depth(png, info);
    header->channels = png_get_channels(png, info);
    const int colour_type = png_get_color_type(png, info);
    if (colour_type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (colour_type == PNG_COLOR_TYPE_GRAY && header->bit_depth < 8) {
        png_set_expand_gray_1_2_4_to_8(png);
    }
    if (header->bit_depth == 16) png_set_scale_16(png);  // rounds v * 255 / 65535
    // An alpha channel, or the one a palette's tRNS chunk becomes when expanded.
    png_set_strip_alpha(png);
    if (!(colour_type & PNG_COLOR_MASK_COLOR)) png_set_gray_to_rgb(png);
    png_set_interlace_handling(png);
    png_read_update_info(png, info);
    header->rgb_row_bytes = png_get_rowbytes(png, info);
    return true;
}

/// Reads the rows into `rows` and the chunks after them; false after a libpng error.
bool png_read_rows(png_structp png, png_infop info, png_bytepp rows) {
    if (setjmp(png_jmpbuf(png))) return false;
    png_read_image(png, rows);
    png_read_end(png, info);
    return true;
}

/// Frees libpng's read structures however the read ended.
struct PngReadStructs {
    png_structp png = nullptr;
    png_infop info = nullptr;
    ~PngReadStructs() {
        if (png != nullptr)
            png_destroy_read_struct(&png, info != nullptr ? &info : nullptr, nullptr);
    }
};

// Deflate compresses at most 1032:1, so a file claims more pixels than it holds when its pixel
// bytes exceed this many times its size; checked before the image is allocated.
constexpr double kMaxDeflateRatio = 1032.0;

}  // namespace
}  // namespace png_image_internal

RgbImage::RgbImage(int width, int height, Rgb background) : width_(width), height_(height) {
    if (width < 1 || height < 1 || width > kMaxSide || height > kMaxSide) {
        throw ConfigError("image size " + std::to_string(width) + " x " + std::to_string(height) +
                          " is out of range: each side must be in [1, " + std::to_string(kMaxSide) +
                          "]");
    }
    pixels_.resize(static_cast<std::size_t>(width) * height * 3);
    fill(background);
}

Rgb RgbImage::at(int x, int y) const {
    if (!contains(x, y)) {
        throw std::out_of_range("pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                                ") is outside the " + std::to_string(width_) + " x " +
                                std::to_string(height_) + " image");
    }
    const std::uint8_t* p = &pixels_[(static_cast<std::size_t>(y) * width_ + x) * 3];
    return {p[0], p[1], p[2]};
}

void RgbImage::fill(Rgb colour) {
    for (std::size_t i = 0; i < pixels_.size(); i += 3) {
        pixels_[i] = colour.r;
        pixels_[i + 1] = colour.g;
        pixels_[i + 2] = colour.b;
    }
}

void RgbImage::write_png(const std::filesystem::path& path) const {
    write_file_atomically(path, [&](const std::filesystem::path& tmp) {
        // libpng's simplified API reports errors in image.message instead of longjmp-ing through
        // our frames.
        png_image image;
        std::memset(&image, 0, sizeof(image));
        image.version = PNG_IMAGE_VERSION;
        image.width = static_cast<png_uint_32>(width_);
        image.height = static_cast<png_uint_32>(height_);
        image.format = PNG_FORMAT_RGB;
        const int ok = png_image_write_to_file(&image, tmp.c_str(), 0, pixels_.data(),
                                               static_cast<png_int_32>(width_) * 3, nullptr);
        if (!ok) {
            const std::string message = image.message;
            png_image_free(&image);
            throw IoError("cannot write PNG '" + path.string() + "': " + message);
        }
    });
}

RgbImage RgbImage::parse_png(std::string_view data, const std::filesystem::path& source) {
    using namespace png_image_internal;
    const std::string name = "PNG file '" + source.string() + "'";
    if (data.size() < 8 || png_sig_cmp(reinterpret_cast<png_const_bytep>(data.data()), 0, 8) != 0) {
        throw IoError(
            name + " is not a PNG image (" +
            (data.empty() ? std::string("it is empty") : "no PNG signature in its first 8 bytes") +
            "): expected a PNG image");
    }
    PngReadContext context;
    context.data = reinterpret_cast<const unsigned char*>(data.data());
    context.size = data.size();
    PngReadStructs structs;
    structs.png =
        png_create_read_struct(PNG_LIBPNG_VER_STRING, &context, png_on_error, png_on_warning);
    if (structs.png != nullptr) structs.info = png_create_info_struct(structs.png);
    if (structs.info == nullptr) throw IoError("cannot read " + name + ": out of memory");
    png_set_read_fn(structs.png, &context, png_read_from_context);
    png_set_user_limits(structs.png, kMaxSide, kMaxSide);
    const auto fail = [&](const std::string& what) {
        throw IoError(name + " is corrupt or truncated (libpng: " + what + ")");
    };

    PngHeader header;
    if (!png_read_header_rgb8(structs.png, structs.info, &header)) fail(context.message);
    const double pixel_bytes = static_cast<double>(header.width) * header.height * header.channels *
                               header.bit_depth / 8.0;
    if (pixel_bytes > kMaxDeflateRatio * static_cast<double>(data.size())) {
        throw IoError(name + " claims " + std::to_string(header.width) + " x " +
                      std::to_string(header.height) + " pixels, more than its " +
                      std::to_string(data.size()) +
                      " bytes can hold: the file is truncated or corrupt");
    }
    // png_set_user_limits made libpng reject sides above kMaxSide; zero sides are its error too.
    RgbImage image(static_cast<int>(header.width), static_cast<int>(header.height));
    if (header.rgb_row_bytes != static_cast<png_size_t>(image.width_) * 3) {
        fail("unexpected row size " + std::to_string(header.rgb_row_bytes) + " after conversion");
    }
    std::vector<png_bytep> rows(header.height);
    for (png_uint_32 y = 0; y < header.height; ++y) {
        rows[y] = image.pixels_.data() + static_cast<std::size_t>(y) * image.width_ * 3;
    }
    if (!png_read_rows(structs.png, structs.info, rows.data())) fail(context.message);
    return image;
}

RgbImage RgbImage::read_png(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::error_code ec;
    if (!in || std::filesystem::is_directory(path, ec)) {
        throw IoError("cannot open PNG file '" + path.string() +
                      "': it does not exist, is a directory or is not readable");
    }
    const std::string data((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    if (in.bad()) throw IoError("cannot read PNG file '" + path.string() + "'");
    return parse_png(data, path);
}

}  // namespace shine
