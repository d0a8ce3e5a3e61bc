// Reading a whole input file into memory, with the checks every reader needs first, the
// quoting every reader's error messages use, and the number lists of text calibration files.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

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

/// Parses every blank-separated word of `text` as a double (a leading '+' allowed) into
/// `values`. Returns false with `bad` set to printable_excerpt() of the first word that is not
/// a number.
bool parse_number_words(std::string_view text, std::vector<double>* values, std::string* bad);

}  // namespace shine
