#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"

namespace fs = std::filesystem;

TEST(AtomicFile, FailedWriteLeavesOldFileAndNoTemporary) {
    const fs::path dir = fs::path(SHINE_TEST_TMP_DIR) / "atomic";
    fs::remove_all(dir);
    shine::ensure_directory(dir);
    const fs::path target = dir / "out.txt";
    shine::write_stream_atomically(target, [](std::ostream& out) { out << "old"; });
    EXPECT_THROW(shine::write_stream_atomically(target,
                                                [](std::ostream& out) {
                                                    out << "half";
                                                    throw shine::IoError("simulated failure");
                                                }),
                 shine::IoError);
    std::ifstream in(target);
    std::string content;
    in >> content;
    EXPECT_EQ(content, "old");
    int entries = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++entries;
    EXPECT_EQ(entries, 1) << "a temporary file was left behind";
}
