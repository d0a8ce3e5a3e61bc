#include "cli_common.hpp"

#include <sys/resource.h>

#include <cstdlib>
#include <thread>

namespace shine::cli {

std::unique_ptr<tbb::global_control> limit_threads(int threads) {
    const int n =
        threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, n);
}

std::size_t peak_rss_bytes() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return static_cast<std::size_t>(usage.ru_maxrss) * 1024;  // Linux reports KiB
}

std::filesystem::path bundled_example_dir() {
    if (const char* env = std::getenv("SHINE_EXAMPLE_DIR")) return env;
    return std::filesystem::path(SHINE_SOURCE_DIR) / "examples" / "street";
}

}  // namespace shine::cli
