// Reading a whole input file into memory, with the checks every reader needs first, and the
// quoting every reader's error messages use.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace shine {

/// Whether a zero-byte file is valid input for a reader.
enum class EmptyFile { kReject, kAllow };

/// Returns the bytes of `path`. Throws IoError "<kind> '<path>': <problem>" when the file is
/// missing, a directory (the message says `expected`, e.g. "a .ply file"), unreadable, or empty
/// under EmptyFile::kReject.
std::string read_file_contents(const std::filesystem::path& path, const std::string& kind,
                               const std::string& expected = "a file",
                               EmptyFile empty = EmptyFile::kReject);

/// `text` made safe to quote in an error message: bytes outside printable ASCII become \xNN and
/// anything past `max_chars` is cut and marked with "...", so a binary file given to a text
/// reader gives a short, readable message.
std::string printable_excerpt(std::string_view text, std::size_t max_chars = 40);

}  // namespace shine
