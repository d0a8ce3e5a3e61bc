// Elapsed wall time, for the stage timings of stats.json, the progress lines and the benchmarks.
#pragma once

#include <chrono>

namespace shine {

/// Seconds on the steady clock since `start`.
inline double seconds_since(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace shine
