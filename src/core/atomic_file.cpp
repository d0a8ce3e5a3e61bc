#include "shine/core/atomic_file.hpp"

#include <atomic>
#include <cstdio>
#include <system_error>
#include <unistd.h>

#include "shine/core/error.hpp"

namespace shine {
namespace fs = std::filesystem;

namespace {
fs::path temporary_name(const fs::path& path) {
    static std::atomic<unsigned> counter{0};
    return path.parent_path() / ("." + path.filename().string() + ".tmp." +
                                 std::to_string(::getpid()) + "." + std::to_string(counter++));
}
}  // namespace

void ensure_directory(const fs::path& dir) {
    if (dir.empty()) return;
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec || !fs::is_directory(dir)) {
        throw IoError("cannot create output directory '" + dir.string() + "': " +
                      (ec ? ec.message() : std::string("a file of that name exists")));
    }
}

void write_file_atomically(const fs::path& path,
                           const std::function<void(const fs::path& tmp_path)>& write) {
    const fs::path tmp = temporary_name(path);
    try {
        write(tmp);
        std::error_code ec;
        fs::rename(tmp, path, ec);
        if (ec) throw IoError("cannot rename '" + tmp.string() + "' to '" + path.string() + "': " +
                              ec.message());
    } catch (...) {
        std::error_code ignored;
        fs::remove(tmp, ignored);
        throw;
    }
}

void write_stream_atomically(const fs::path& path,
                             const std::function<void(std::ostream& out)>& write) {
    write_file_atomically(path, [&](const fs::path& tmp) {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) throw IoError("cannot open '" + path.string() + "' for writing");
        write(out);
        out.flush();
        if (!out) throw IoError("failed while writing '" + path.string() + "' (disk full?)");
    });
}

}  // namespace shine
