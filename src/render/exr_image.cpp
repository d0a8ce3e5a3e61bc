#include "shine/render/exr_image.hpp"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfInputFile.h>
#include <ImfOutputFile.h>
#include <ImfStringAttribute.h>

#include <algorithm>
#include <exception>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"

namespace shine {
namespace {
constexpr int kMaxSide = 1 << 15;
}  // namespace

ExrImage::ExrImage(int width, int height) : width_(width), height_(height) {
    if (width < 1 || height < 1 || width > kMaxSide || height > kMaxSide) {
        throw ConfigError("EXR image size " + std::to_string(width) + " x " +
                          std::to_string(height) + " is out of range: each side must be in [1, " +
                          std::to_string(kMaxSide) + "]");
    }
}

void ExrImage::add_channel(const std::string& name, std::vector<float> values) {
    if (name.empty()) throw DataError("an EXR channel needs a name");
    if (has_channel(name)) throw DataError("EXR channel '" + name + "' is already present");
    if (values.size() != num_pixels()) {
        throw DataError("EXR channel '" + name + "' has " + std::to_string(values.size()) +
                        " values for a " + std::to_string(width_) + " x " +
                        std::to_string(height_) + " image");
    }
    channels_.emplace_back(name, std::move(values));
}

bool ExrImage::has_channel(const std::string& name) const {
    return std::any_of(channels_.begin(), channels_.end(),
                       [&](const auto& c) { return c.first == name; });
}

const std::vector<float>& ExrImage::channel(const std::string& name) const {
    for (const auto& c : channels_) {
        if (c.first == name) return c.second;
    }
    std::string present;
    for (const auto& c : channels_) present += (present.empty() ? "" : ", ") + c.first;
    throw DataError("EXR image has no channel '" + name + "' (channels: " + present + ")");
}

std::vector<std::string> ExrImage::channel_names() const {
    std::vector<std::string> names;
    for (const auto& c : channels_) names.push_back(c.first);
    return names;
}

void write_exr(const std::filesystem::path& path, const ExrImage& image) {
    if (image.channel_names().empty()) {
        throw DataError("cannot write EXR '" + path.string() + "': the image has no channels");
    }
    write_file_atomically(path, [&](const std::filesystem::path& tmp) {
        try {
            Imf::Header header(image.width(), image.height());
            header.compression() = Imf::ZIP_COMPRESSION;
            for (const auto& [key, value] : image.attributes) {
                header.insert(key, Imf::StringAttribute(value));
            }
            Imf::FrameBuffer frame;
            const std::size_t x_stride = sizeof(float);
            const std::size_t y_stride = sizeof(float) * image.width();
            for (const std::string& name : image.channel_names()) {
                header.channels().insert(name, Imf::Channel(Imf::FLOAT));
                // OpenEXR only reads through the pointer while writing.
                char* base =
                    reinterpret_cast<char*>(const_cast<float*>(image.channel(name).data()));
                frame.insert(name, Imf::Slice(Imf::FLOAT, base, x_stride, y_stride));
            }
            Imf::OutputFile file(tmp.c_str(), header);
            file.setFrameBuffer(frame);
            file.writePixels(image.height());
        } catch (const std::exception& e) {
            throw IoError("cannot write EXR '" + path.string() + "': " + e.what());
        }
    });
}

ExrImage read_exr(const std::filesystem::path& path) {
    if (!std::filesystem::is_regular_file(path)) {
        throw IoError("EXR file '" + path.string() + "' does not exist");
    }
    try {
        Imf::InputFile file(path.c_str());
        const Imath::Box2i window = file.header().dataWindow();
        const int width = window.max.x - window.min.x + 1;
        const int height = window.max.y - window.min.y + 1;
        ExrImage image(width, height);
        std::vector<std::pair<std::string, std::vector<float>>> channels;
        for (auto it = file.header().channels().begin(); it != file.header().channels().end();
             ++it) {
            channels.emplace_back(it.name(), std::vector<float>(image.num_pixels()));
        }
        Imf::FrameBuffer frame;
        const std::size_t x_stride = sizeof(float);
        const std::size_t y_stride = sizeof(float) * width;
        for (auto& [name, values] : channels) {
            // The slice's base points at pixel (0, 0) of the file's coordinates.
            char* base =
                reinterpret_cast<char*>(values.data()) -
                (std::ptrdiff_t(window.min.x) * x_stride + std::ptrdiff_t(window.min.y) * y_stride);
            frame.insert(name, Imf::Slice(Imf::FLOAT, base, x_stride, y_stride));
        }
        file.setFrameBuffer(frame);
        file.readPixels(window.min.y, window.max.y);
        for (auto& [name, values] : channels) image.add_channel(name, std::move(values));
        for (auto it = file.header().begin(); it != file.header().end(); ++it) {
            if (const auto* s = dynamic_cast<const Imf::StringAttribute*>(&it.attribute())) {
                image.attributes[it.name()] = s->value();
            }
        }
        return image;
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        throw IoError("cannot read EXR '" + path.string() + "': " + e.what());
    }
}

}  // namespace shine
