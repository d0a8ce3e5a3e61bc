// libFuzzer target: PNG images (RgbImage::parse_png, the camera images of io/camera_rig.hpp):
// any colour type, bit depth and interlacing, damaged files included. libpng's errors must end in
// a shine::Error naming the input, without leaks; an accepted image has the size it claims.
#include <cstdlib>

#include "fuzz_common.hpp"
#include "shine/core/png_image.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    shine_fuzz::expect_value_or_error([&] {
        const shine::RgbImage image =
            shine::RgbImage::parse_png(shine_fuzz::as_view(data, size), shine_fuzz::kSource);
        if (image.width() < 1 || image.height() < 1 ||
            image.pixels().size() != static_cast<std::size_t>(image.width()) * image.height() * 3) {
            std::abort();
        }
    });
    return 0;
}
