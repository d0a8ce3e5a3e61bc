// Private helpers of the recording readers: bounds-checked little-endian reads from a byte range,
// ranged file reads, and the chunk decompressors (bz2, lz4 frames, zstd). Every failure is an
// IoError naming the file, the byte offset and what was being read.
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/io/recording.hpp"

namespace shine::recording_internal {

/// Largest uncompressed chunk or single message accepted (real chunks are 0.7-4 MB; a single
/// PointCloud2 of a 128-beam sensor is about 10 MB). Larger claims are treated as corruption.
constexpr std::uint64_t kMaxBlockBytes = 256ull << 20;

/// Reads little-endian values from `data`; `base` is the file offset of data[0] for messages.
class ByteCursor {
  public:
    ByteCursor(std::string_view data, const std::filesystem::path& source, std::string kind,
               std::uint64_t base = 0)
        : data_(data), source_(source), kind_(std::move(kind)), base_(base) {}

    template <class T>
    T value(const char* what) {
        T v;
        std::memcpy(&v, take(sizeof(T), what), sizeof(T));
        return v;
    }
    std::uint8_t u8(const char* what) { return value<std::uint8_t>(what); }
    std::uint16_t u16(const char* what) { return value<std::uint16_t>(what); }
    std::uint32_t u32(const char* what) { return value<std::uint32_t>(what); }
    std::uint64_t u64(const char* what) { return value<std::uint64_t>(what); }
    /// `bytes` raw bytes.
    std::string_view bytes(std::uint64_t bytes, const char* what) {
        return {take(bytes, what), static_cast<std::size_t>(bytes)};
    }
    /// Skips to `alignment` relative to the start of the range (CDR alignment).
    void align(std::size_t alignment) {
        const std::size_t pad = (alignment - pos_ % alignment) % alignment;
        take(pad, "alignment padding");
    }
    std::size_t position() const { return pos_; }
    std::size_t remaining() const { return data_.size() - pos_; }
    bool at_end() const { return pos_ == data_.size(); }
    std::string_view rest() { return bytes(remaining(), "rest"); }

    [[noreturn]] void fail(const std::string& problem) const {
        throw IoError(kind_ + " '" + source_.string() + "', byte " + std::to_string(base_ + pos_) +
                      ": " + problem);
    }

  private:
    const char* take(std::uint64_t n, const char* what) {
        if (n > data_.size() - pos_) {
            fail(std::string("truncated: ") + what + " needs " + std::to_string(n) +
                 " bytes, only " + std::to_string(data_.size() - pos_) +
                 " left (is the recording complete?)");
        }
        const char* p = data_.data() + pos_;
        pos_ += static_cast<std::size_t>(n);
        return p;
    }

    std::string_view data_;
    const std::filesystem::path& source_;
    std::string kind_;
    std::uint64_t base_;
    std::size_t pos_ = 0;
};

/// A recording file opened for ranged reads.
class RangedFile {
  public:
    RangedFile(const std::filesystem::path& path, std::string kind);
    std::uint64_t size() const { return size_; }
    /// Reads `bytes` at `offset`; IoError (naming `what`) if the range passes the end of file.
    std::string read(std::uint64_t offset, std::uint64_t bytes, const char* what);
    const std::filesystem::path& path() const { return path_; }
    const std::string& kind() const { return kind_; }

  private:
    std::filesystem::path path_;
    std::string kind_;
    std::ifstream in_;
    std::uint64_t size_ = 0;
};

/// Decompresses a whole block whose uncompressed size is known. `compression` is "bz2", "lz4"
/// (an LZ4 frame, as ROS 1's roslz4 and MCAP write) or "zstd"; "" or "none" copies. Throws
/// IoError naming `source`, `offset` and the problem (corrupt data, a size mismatch, an unknown
/// compression, a size over kMaxBlockBytes).
std::string decompress_block(std::string_view compressed, const std::string& compression,
                             std::uint64_t uncompressed_bytes, const std::filesystem::path& source,
                             const std::string& kind, std::uint64_t offset);

/// The messages of `topic` over every connection (ROS 1) or channel (MCAP) that carries it,
/// merged in log time; ties keep file order (block, then offset). `connections` maps an id to a
/// record with a `topic`; `messages` maps the same id to its indexed messages.
template <class Connections, class MessagesById>
std::vector<RecordingMessage> topic_messages_in_time(const Connections& connections,
                                                     const MessagesById& messages,
                                                     const std::string& topic) {
    std::vector<RecordingMessage> out;
    for (const auto& [id, connection] : connections) {
        if (connection.topic != topic) continue;
        const auto it = messages.find(id);
        if (it != messages.end()) out.insert(out.end(), it->second.begin(), it->second.end());
    }
    std::stable_sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
        if (a.log_time_ns != b.log_time_ns) return a.log_time_ns < b.log_time_ns;
        return a.block != b.block ? a.block < b.block : a.offset < b.offset;
    });
    return out;
}

}  // namespace shine::recording_internal
