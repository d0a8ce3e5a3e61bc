// Reading a whole input file into memory, with the checks every reader needs first.
#pragma once

#include <filesystem>
#include <string>

namespace shine {

/// Returns the bytes of `path`. Throws IoError "<kind> '<path>': <problem>" when the file is
/// missing, a directory (the message says `expected`, e.g. "a .ply file"), unreadable or empty.
std::string read_file_contents(const std::filesystem::path& path, const std::string& kind,
                               const std::string& expected = "a file");

}  // namespace shine
