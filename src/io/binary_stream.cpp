#include "shine/io/binary_stream.hpp"

#include "shine/core/error.hpp"
#include "shine/io/file_contents.hpp"

namespace shine {

void BinaryWriter::string(const std::string& s) {
    value<std::uint64_t>(s.size());
    out_.write(s.data(), static_cast<std::streamsize>(s.size()));
}

BinaryReader::BinaryReader(const std::filesystem::path& path, const std::string& kind)
    : path_(path), kind_(kind), bytes_(read_file_contents(path, kind)) {}

void BinaryReader::fail(const std::string& what, const std::string& problem) const {
    throw IoError(kind_ + " '" + path_.string() + "', byte " + std::to_string(offset_) + ": " +
                  what + " " + problem);
}

const char* BinaryReader::take(std::size_t bytes, const char* what) {
    const std::size_t left = bytes_.size() - offset_;
    if (bytes > left) {
        fail(what, "needs " + std::to_string(bytes) + " bytes but the file ends after " +
                       std::to_string(left) + " (truncated?)");
    }
    const char* p = bytes_.data() + offset_;
    offset_ += bytes;
    return p;
}

std::size_t BinaryReader::array_length(std::size_t element_size, const char* what) {
    const auto count = value<std::uint64_t>(what);
    const auto stored_size = value<std::uint32_t>(what);
    if (stored_size != element_size) {
        fail(what, "has " + std::to_string(stored_size) + "-byte values, expected " +
                       std::to_string(element_size) + " (written by another version?)");
    }
    if (count > (bytes_.size() - offset_) / element_size) {
        fail(what, "claims " + std::to_string(count) + " values, more than the " +
                       std::to_string(bytes_.size() - offset_) +
                       " bytes left in the file hold (truncated?)");
    }
    return static_cast<std::size_t>(count);
}

std::string BinaryReader::string(const char* what) {
    const auto length = value<std::uint64_t>(what);
    if (length > bytes_.size() - offset_) {
        fail(what, "claims " + std::to_string(length) + " bytes, more than the " +
                       std::to_string(bytes_.size() - offset_) + " left (truncated?)");
    }
    return std::string(take(static_cast<std::size_t>(length), what),
                       static_cast<std::size_t>(length));
}

void BinaryReader::expect_tag(const std::string& name) {
    const std::size_t at = offset_;
    const std::string found = string(("section '" + name + "'").c_str());
    if (found != name) {
        offset_ = at;
        fail("section '" + name + "'", "expected, found '" + printable_excerpt(found) +
                                           "' (a file of another version or kind?)");
    }
}

bool BinaryReader::next_is_tag(const std::string& name) const {
    const std::uint64_t length = name.size();
    if (bytes_.size() - offset_ < sizeof(length) + name.size()) return false;
    return std::memcmp(bytes_.data() + offset_, &length, sizeof(length)) == 0 &&
           bytes_.compare(offset_ + sizeof(length), name.size(), name) == 0;
}

void BinaryReader::expect_end() const {
    if (offset_ != bytes_.size()) {
        throw IoError(kind_ + " '" + path_.string() +
                      "': " + std::to_string(bytes_.size() - offset_) +
                      " unexpected bytes after byte " + std::to_string(offset_));
    }
}

}  // namespace shine
