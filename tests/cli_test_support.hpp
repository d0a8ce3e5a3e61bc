// What the tests that run the `shine` executable share: a directory per test, running a command
// with its output captured, and reading back what it wrote.
//
// ctest runs each test in its own process, in parallel, so every test works in its own directory
// <SHINE_TEST_TMP_DIR>/<suite>/<test name>. SHINE_TEST_TMP_DIR and SHINE_CLI_PATH are set by
// tests/CMakeLists.txt. A test that passes removes its directory when it ends (streets, maps and
// meshes add up to gigabytes over the whole suite); a failed test keeps it for a look, and so does
// every test when SHINE_KEEP_TEST_DIRS is set.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

namespace shine::cli_test {

namespace fs = std::filesystem;

struct CliResult {
    int exit_code;
    std::string output;  ///< stdout and stderr, interleaved
};

/// The directories test_dir_of() made for the running test.
inline std::vector<fs::path>& dirs_of_running_test() {
    static std::vector<fs::path> dirs;
    return dirs;
}

/// Removes the running test's directories when it passed (see the top of this file).
class RemoveDirsOfPassedTests : public ::testing::EmptyTestEventListener {
    void OnTestEnd(const ::testing::TestInfo& info) override {
        std::vector<fs::path>& dirs = dirs_of_running_test();
        if (info.result()->Passed() && std::getenv("SHINE_KEEP_TEST_DIRS") == nullptr) {
            for (const fs::path& d : dirs) {
                std::error_code ignored;  // a directory left behind costs disk, not correctness
                fs::remove_all(d, ignored);
            }
        }
        dirs.clear();
    }
};

inline const bool kRemovesDirsOfPassedTests = [] {
    ::testing::UnitTest::GetInstance()->listeners().Append(new RemoveDirsOfPassedTests);
    return true;
}();

/// <SHINE_TEST_TMP_DIR>/`suite`/<name of the running test>, created if missing; removed when the
/// test passes.
inline fs::path test_dir_of(const std::string& suite) {
    const fs::path d = fs::path(SHINE_TEST_TMP_DIR) / suite /
                       ::testing::UnitTest::GetInstance()->current_test_info()->name();
    fs::create_directories(d);
    std::vector<fs::path>& dirs = dirs_of_running_test();
    if (std::find(dirs.begin(), dirs.end(), d) == dirs.end()) dirs.push_back(d);
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
