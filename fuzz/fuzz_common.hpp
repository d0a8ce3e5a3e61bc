// Shared pieces of the libFuzzer targets: what counts as a correct answer to bad input, and a
// scratch file for readers that only take paths.
//
// A reader given arbitrary bytes must either return a value or throw a shine::Error (whose
// message names the input). Anything else (a crash, a sanitizer report, another exception
// type, a hang or a huge allocation) is a bug that libFuzzer reports.
#pragma once

#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include "shine/core/error.hpp"

namespace shine_fuzz {

/// The name readers use for the input in their messages.
inline const std::filesystem::path kSource = "fuzz-input";

inline std::string_view as_view(const std::uint8_t* data, std::size_t size) {
    return {reinterpret_cast<const char*>(data), size};
}

/// Runs `f`; a shine::Error is an accepted outcome, but its message must name the input.
template <typename F>
void expect_value_or_error(F&& f) {
    try {
        f();
    } catch (const shine::Error& e) {
        if (std::string_view(e.what()).find(kSource.string()) == std::string_view::npos) {
            std::fprintf(stderr, "error message does not name the input: %s\n", e.what());
            std::abort();
        }
    }
}

/// A per-process scratch file (so parallel fuzzing jobs do not share it), removed at exit.
class ScratchFile {
  public:
    explicit ScratchFile(const std::string& extension)
        : path_(std::filesystem::temp_directory_path() /
                ("shine_fuzz_" + std::to_string(::getpid()) + extension)) {}
    ~ScratchFile() {
        std::error_code ec;
        std::filesystem::remove(path_, ec);
    }
    const std::filesystem::path& write(std::string_view bytes) {
        std::ofstream out(path_, std::ios::binary | std::ios::trunc);
        out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
        if (!out) {
            std::fprintf(stderr, "cannot write scratch file %s\n", path_.c_str());
            std::abort();
        }
        return path_;
    }

  private:
    std::filesystem::path path_;
};

}  // namespace shine_fuzz
