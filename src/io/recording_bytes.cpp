// Private helpers of the recording readers: ranged file reads and chunk decompression.
#include "recording_bytes.hpp"

#include <bzlib.h>
#include <lz4frame.h>
#include <zstd.h>

#include <limits>
#include <memory>

namespace shine::recording_internal {
namespace fs = std::filesystem;

RangedFile::RangedFile(const fs::path& path, std::string kind)
    : path_(path), kind_(std::move(kind)) {
    std::error_code ec;
    if (!fs::is_regular_file(path, ec)) {
        throw IoError(kind_ + " '" + path.string() + "' does not exist or is not a file");
    }
    size_ = fs::file_size(path, ec);
    if (ec) throw IoError("cannot read the size of " + kind_ + " '" + path.string() + "'");
    in_.open(path, std::ios::binary);
    if (!in_) throw IoError("cannot open " + kind_ + " '" + path.string() + "' for reading");
}

std::string RangedFile::read(std::uint64_t offset, std::uint64_t bytes, const char* what) {
    if (offset > size_ || bytes > size_ - offset) {
        throw IoError(kind_ + " '" + path_.string() + "', byte " + std::to_string(offset) +
                      ": truncated: " + what + " needs " + std::to_string(bytes) +
                      " bytes, the file ends after " +
                      std::to_string(offset > size_ ? 0 : size_ - offset) +
                      " (is the recording complete?)");
    }
    std::string out(static_cast<std::size_t>(bytes), '\0');
    in_.clear();
    in_.seekg(static_cast<std::streamoff>(offset));
    in_.read(out.data(), static_cast<std::streamsize>(bytes));
    if (!in_) {
        throw IoError("cannot read " + std::string(what) + " of " + kind_ + " '" + path_.string() +
                      "' at byte " + std::to_string(offset));
    }
    return out;
}

std::string decompress_block(std::string_view compressed, const std::string& compression,
                             std::uint64_t uncompressed_bytes, const fs::path& source,
                             const std::string& kind, std::uint64_t offset) {
    const auto fail = [&](const std::string& problem) -> IoError {
        return IoError(kind + " '" + source.string() + "', chunk at byte " +
                       std::to_string(offset) + ": " + problem);
    };
    if (compression.empty() || compression == "none") {
        if (compressed.size() != uncompressed_bytes) {
            throw fail("uncompressed chunk holds " + std::to_string(compressed.size()) +
                       " bytes but its header says " + std::to_string(uncompressed_bytes));
        }
        return std::string(compressed);
    }
    if (uncompressed_bytes > kMaxBlockBytes) {
        throw fail("claims " + std::to_string(uncompressed_bytes) +
                   " bytes uncompressed, more than the " + std::to_string(kMaxBlockBytes >> 20) +
                   " MiB a chunk may hold (corrupt header?)");
    }
    std::string out(static_cast<std::size_t>(uncompressed_bytes), '\0');
    if (compression == "bz2") {
        if (compressed.size() > std::numeric_limits<unsigned int>::max()) {
            throw fail("bz2 chunk too large");
        }
        unsigned int out_len = static_cast<unsigned int>(out.size());
        const int rc =
            BZ2_bzBuffToBuffDecompress(out.data(), &out_len, const_cast<char*>(compressed.data()),
                                       static_cast<unsigned int>(compressed.size()), 0, 0);
        if (rc != BZ_OK) {
            throw fail("bz2 data is corrupt or truncated (libbz2 error " + std::to_string(rc) +
                       ")");
        }
        if (out_len != out.size()) {
            throw fail("bz2 data holds " + std::to_string(out_len) + " bytes, the header says " +
                       std::to_string(out.size()));
        }
        return out;
    }
    if (compression == "lz4") {
        LZ4F_dctx* raw = nullptr;
        if (LZ4F_isError(LZ4F_createDecompressionContext(&raw, LZ4F_VERSION))) {
            throw fail("cannot create an LZ4 decompression context");
        }
        const std::unique_ptr<LZ4F_dctx, decltype(&LZ4F_freeDecompressionContext)> dctx(
            raw, &LZ4F_freeDecompressionContext);
        std::size_t in_pos = 0, out_pos = 0;
        std::size_t hint = 1;
        while (hint != 0) {
            std::size_t in_size = compressed.size() - in_pos;
            std::size_t out_size = out.size() - out_pos;
            if (in_size == 0) throw fail("LZ4 frame is truncated");
            hint = LZ4F_decompress(dctx.get(), out.data() + out_pos, &out_size,
                                   compressed.data() + in_pos, &in_size, nullptr);
            if (LZ4F_isError(hint)) {
                throw fail(std::string("LZ4 frame is corrupt (") + LZ4F_getErrorName(hint) + ")");
            }
            in_pos += in_size;
            out_pos += out_size;
            if (hint != 0 && in_size == 0 && out_size == 0) {
                throw fail("LZ4 frame holds more than the " + std::to_string(out.size()) +
                           " bytes its header gives");
            }
        }
        if (out_pos != out.size()) {
            throw fail("LZ4 frame holds " + std::to_string(out_pos) + " bytes, the header says " +
                       std::to_string(out.size()));
        }
        return out;
    }
    if (compression == "zstd") {
        const std::size_t n =
            ZSTD_decompress(out.data(), out.size(), compressed.data(), compressed.size());
        if (ZSTD_isError(n)) {
            throw fail(std::string("zstd data is corrupt (") + ZSTD_getErrorName(n) + ")");
        }
        if (n != out.size()) {
            throw fail("zstd data holds " + std::to_string(n) + " bytes, the header says " +
                       std::to_string(out.size()));
        }
        return out;
    }
    throw fail("unknown compression '" + compression + "' (supported: none, bz2, lz4, zstd)");
}

}  // namespace shine::recording_internal
