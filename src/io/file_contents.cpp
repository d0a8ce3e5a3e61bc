#include "shine/io/file_contents.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cstdio>
#include <fstream>

#include "shine/core/error.hpp"

namespace shine {
namespace fs = std::filesystem;

std::string read_file_contents(const fs::path& path, const std::string& kind,
                               const std::string& expected, EmptyFile empty) {
    auto fail = [&](const std::string& what) {
        throw IoError(kind + " '" + path.string() + "': " + what);
    };
    std::error_code ec;
    if (!fs::exists(path, ec)) fail("file does not exist");
    if (fs::is_directory(path, ec)) fail("is a directory, expected " + expected);
    std::ifstream in(path, std::ios::binary);
    if (!in) fail("cannot open for reading (permissions?)");
    in.seekg(0, std::ios::end);
    const std::streamoff size = in.tellg();
    if (size < 0) fail("cannot determine the file size (not a regular file?)");
    if (size == 0) {
        if (empty == EmptyFile::kAllow) return {};
        fail("file is empty");
    }
    in.seekg(0, std::ios::beg);
    std::string data(static_cast<std::size_t>(size), '\0');
    in.read(data.data(), size);
    if (in.gcount() != size) fail("read error (file changed while reading?)");
    return data;
}

std::string printable_excerpt(std::string_view text, std::size_t max_chars) {
    std::string out;
    const std::size_t n = std::min(text.size(), max_chars);
    for (std::size_t i = 0; i < n; ++i) {
        const auto c = static_cast<unsigned char>(text[i]);
        if (c >= 0x20 && c < 0x7f) {
            out += static_cast<char>(c);
        } else {
            char escaped[8];
            std::snprintf(escaped, sizeof(escaped), "\\x%02x", c);
            out += escaped;
        }
    }
    if (text.size() > max_chars) out += "...";
    return out;
}

bool parse_number_words(std::string_view text, std::vector<double>* values, std::string* bad) {
    values->clear();
    std::size_t i = 0;
    while (i < text.size()) {
        while (i < text.size() && std::isspace(static_cast<unsigned char>(text[i]))) ++i;
        const std::size_t start = i;
        while (i < text.size() && !std::isspace(static_cast<unsigned char>(text[i]))) ++i;
        if (i == start) break;
        const char* first = text.data() + start;
        const char* last = text.data() + i;
        if (*first == '+') ++first;  // from_chars rejects a leading '+'
        double v = 0.0;
        const auto r = std::from_chars(first, last, v);
        if (first == last || r.ec != std::errc() || r.ptr != last) {
            *bad = printable_excerpt(text.substr(start, i - start));
            return false;
        }
        values->push_back(v);
    }
    return true;
}

}  // namespace shine
