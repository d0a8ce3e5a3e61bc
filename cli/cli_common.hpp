// Helpers shared by the subcommands: thread limits, timing, memory, default data location.
#pragma once

#include <tbb/global_control.h>

#include <chrono>
#include <filesystem>
#include <memory>
#include <string>

namespace shine::cli {

/// Limits TBB to `threads` (0 = all hardware threads) for the lifetime of the returned object.
std::unique_ptr<tbb::global_control> limit_threads(int threads);

/// Peak resident set size of this process in bytes.
std::size_t peak_rss_bytes();

/// Where the bundled example street lives (simulated on first use).
std::filesystem::path bundled_example_dir();

/// Seconds since `start`.
inline double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace shine::cli
