// Little-endian binary records for ShineVDB's own state files (the checkpoint of an interrupted
// run): plain values, strings and arrays, each read back with a bounds check, so that a truncated
// or damaged file gives an IoError naming the file, the byte offset and what was being read,
// never a crash or a silently wrong state.
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <ostream>
#include <string>
#include <type_traits>
#include <vector>

namespace shine {

/// Appends records to a stream. Values are written in the machine's byte order (x86-64 and
/// AArch64 are both little-endian; the file's header records it, see BinaryReader::expect_tag).
class BinaryWriter {
  public:
    explicit BinaryWriter(std::ostream& out) : out_(out) {}

    template <class T>
    void value(const T& v) {
        static_assert(std::is_trivially_copyable_v<T>, "only plain values are written raw");
        out_.write(reinterpret_cast<const char*>(&v), sizeof(T));
    }
    /// A length-prefixed string.
    void string(const std::string& s);
    /// A length-prefixed array of plain values.
    template <class T>
    void array(const std::vector<T>& v) {
        array(v.data(), v.size());
    }
    template <class T>
    void array(const T* data, std::size_t count) {
        static_assert(std::is_trivially_copyable_v<T>, "only plain values are written raw");
        value<std::uint64_t>(count);
        value<std::uint32_t>(static_cast<std::uint32_t>(sizeof(T)));
        out_.write(reinterpret_cast<const char*>(data),
                   static_cast<std::streamsize>(count * sizeof(T)));
    }
    /// A section name: the reader checks it with expect_tag(), so a file of another layout or
    /// version stops at the first section that differs.
    void tag(const std::string& name) { string(name); }

  private:
    std::ostream& out_;
};

/// Reads a whole file and hands out its records in order.
class BinaryReader {
  public:
    /// Reads `path` (IoError if it is missing, unreadable or empty); `kind` names the file in
    /// messages ("checkpoint").
    BinaryReader(const std::filesystem::path& path, const std::string& kind);

    template <class T>
    T value(const char* what) {
        static_assert(std::is_trivially_copyable_v<T>, "only plain values are read raw");
        T v;
        std::memcpy(&v, take(sizeof(T), what), sizeof(T));
        return v;
    }
    std::string string(const char* what);
    template <class T>
    std::vector<T> array(const char* what) {
        std::vector<T> v(array_length(sizeof(T), what));
        if (!v.empty())
            std::memcpy(v.data(), take(v.size() * sizeof(T), what), v.size() * sizeof(T));
        return v;
    }
    /// Reads an array into `out`, which must already have exactly `expected` elements.
    template <class T>
    void array_into(T* out, std::size_t expected, const char* what) {
        const std::size_t n = array_length(sizeof(T), what);
        if (n != expected)
            fail(what,
                 "holds " + std::to_string(n) + " values, expected " + std::to_string(expected));
        if (n) std::memcpy(out, take(n * sizeof(T), what), n * sizeof(T));
    }
    /// Throws IoError unless the next record is the section name `name`.
    void expect_tag(const std::string& name);
    /// Whether the next record is the section name `name` (reads nothing).
    bool next_is_tag(const std::string& name) const;
    /// Throws IoError unless every byte has been read.
    void expect_end() const;

    /// Throws IoError "<kind> '<path>', byte <offset>: <what> <problem>".
    [[noreturn]] void fail(const std::string& what, const std::string& problem) const;
    const std::filesystem::path& path() const { return path_; }
    std::size_t offset() const { return offset_; }

  private:
    const char* take(std::size_t bytes, const char* what);
    std::size_t array_length(std::size_t element_size, const char* what);

    std::filesystem::path path_;
    std::string kind_;
    std::string bytes_;
    std::size_t offset_ = 0;
};

}  // namespace shine
