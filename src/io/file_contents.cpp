#include "shine/io/file_contents.hpp"

#include <fstream>

#include "shine/core/error.hpp"

namespace shine {
namespace fs = std::filesystem;

std::string read_file_contents(const fs::path& path, const std::string& kind,
                               const std::string& expected) {
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
    if (size < 0) fail("cannot determine the file size");
    if (size == 0) fail("file is empty");
    in.seekg(0, std::ios::beg);
    std::string data(static_cast<std::size_t>(size), '\0');
    in.read(data.data(), size);
    if (in.gcount() != size) fail("read error (file changed while reading?)");
    return data;
}

}  // namespace shine
