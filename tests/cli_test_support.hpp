// What the tests that run the `shine` executable share: a directory per test, running a command
// with its output captured, and reading back what it wrote.
//
// ctest runs each test in its own process, in parallel, so every test works in its own directory
// <SHINE_TEST_TMP_DIR>/<suite>/<test name>. SHINE_TEST_TMP_DIR and SHINE_CLI_PATH are set by
// tests/CMakeLists.txt.
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

namespace shine::cli_test {

namespace fs = std::filesystem;

struct CliResult {
    int exit_code;
    std::string output;  ///< stdout and stderr, interleaved
};

/// <SHINE_TEST_TMP_DIR>/`suite`/<name of the running test>, created if missing.
inline fs::path test_dir_of(const std::string& suite) {
    const fs::path d = fs::path(SHINE_TEST_TMP_DIR) / suite /
                       ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(d);
    return d;
}

inline std::string read_text(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream text;
    text << in.rdbuf();
    return text.str();
}

inline nlohmann::json read_json(const fs::path& path) {
    std::ifstream in(path);
    return nlohmann::json::parse(in);
}

/// Runs `shine <args>` (args are passed to the shell as they are: quote paths in them), with
/// stdout and stderr captured in `dir`/last_command.log.
inline CliResult run_shine(const std::string& args, const fs::path& dir) {
    const fs::path log = dir / "last_command.log";
    const std::string command =
        "'" + std::string(SHINE_CLI_PATH) + "' " + args + " > '" + log.string() + "' 2>&1";
    const int status = std::system(command.c_str());
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, read_text(log)};
}

/// Simulates a street of `frames` scans with `seed` into `dir` (replacing it); a failure is
/// reported as a test failure with the command's output.
inline void simulate_street(const fs::path& dir, int frames, int seed) {
    fs::remove_all(dir);
    const CliResult r =
        run_shine("simulate -o '" + dir.string() + "' --frames " + std::to_string(frames) +
                      " --seed " + std::to_string(seed) + " --no-progress",
                  dir.parent_path());
    EXPECT_EQ(r.exit_code, 0) << r.output;
}

}  // namespace shine::cli_test
