// Atomic file output: write to a temporary name beside the target, then rename.
//
// A run that fails or is interrupted never leaves a truncated file under the final name: either
// the old file (or none) is there, or the complete new one.
#pragma once

#include <filesystem>
#include <fstream>
#include <functional>
#include <string>

namespace shine {

/// Writes `path` atomically: `write` receives the temporary path to fill; on success the temporary
/// file is renamed to `path`, on any exception it is removed and the exception propagates.
void write_file_atomically(const std::filesystem::path& path,
                           const std::function<void(const std::filesystem::path& tmp_path)>& write);

/// Convenience for stream writers: opens a binary std::ofstream on the temporary file, calls
/// `write(stream)`, checks the stream state and commits. Throws IoError naming `path` on failure.
void write_stream_atomically(const std::filesystem::path& path,
                             const std::function<void(std::ostream& out)>& write);

/// Creates `dir` and its parents if missing; throws IoError naming it if that fails.
void ensure_directory(const std::filesystem::path& dir);

}  // namespace shine
