// Multi-channel float32 images written to and read from OpenEXR files (OpenEXR 3.1, Debian's
// libopenexr-dev): the format Blender, Nuke and OpenEXR's own tools (exrheader) open.
//
// An ExrImage is a width x height raster of named float channels ("range.V", "normal.X", ...),
// row-major with row 0 at the top, plus string attributes stored in the file's header (how pixels
// map to the world, the units). Files are scan-line images with lossless ZIP compression; NaN is
// stored as NaN. Writes go to a temporary name and are renamed, so a failed write leaves nothing.
#pragma once

#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace shine {

/// Named float32 channels of one size, plus header attributes.
class ExrImage {
  public:
    /// An image of `width` x `height` pixels without channels. Throws ConfigError if a side is
    /// not in [1, 32768].
    ExrImage(int width, int height);

    int width() const { return width_; }
    int height() const { return height_; }
    std::size_t num_pixels() const { return static_cast<std::size_t>(width_) * height_; }

    /// Adds a channel of width * height values (row-major, top row first). Throws DataError for a
    /// wrong size, an empty name or a name already present.
    void add_channel(const std::string& name, std::vector<float> values);
    bool has_channel(const std::string& name) const;
    /// The values of channel `name`; throws DataError naming the channels present if missing.
    const std::vector<float>& channel(const std::string& name) const;
    /// Channel names in the order they were added.
    std::vector<std::string> channel_names() const;

    /// String attributes written to (and read back from) the EXR header.
    std::map<std::string, std::string> attributes;

  private:
    int width_;
    int height_;
    std::vector<std::pair<std::string, std::vector<float>>> channels_;
};

/// Writes `image` to `path` as a float32 scan-line EXR (ZIP compression), atomically. Throws
/// DataError for an image without channels and IoError naming `path` if OpenEXR fails.
void write_exr(const std::filesystem::path& path, const ExrImage& image);

/// Reads every channel of an EXR file as float32 (half and uint channels are converted), and its
/// string attributes. Channels come back in OpenEXR's order (sorted by name). Throws IoError naming
/// `path` for a missing file or one OpenEXR cannot read.
ExrImage read_exr(const std::filesystem::path& path);

}  // namespace shine
