#include "shine/core/png_image.hpp"

#include <png.h>

#include <cstring>
#include <stdexcept>
#include <string>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"

namespace shine {

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

}  // namespace shine
