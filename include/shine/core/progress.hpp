// A progress line on stderr for long loops: "label  [#####.....]  42/100  3.1 s, ETA 4.2 s".
#pragma once

#include <chrono>
#include <cstddef>
#include <string>

namespace shine {

/// Prints a throttled progress line to stderr; silent when disabled (quiet runs, tests).
class Progress {
  public:
    Progress(std::string label, std::size_t total, bool enabled = true);
    ~Progress();
    /// Sets the number of finished steps; redraws at most ten times a second.
    void update(std::size_t done, const std::string& detail = {});
    /// Draws the final state and ends the line.
    void finish(const std::string& detail = {});

    /// Global switch used by the CLI's --quiet flag.
    static void set_globally_enabled(bool enabled);

  private:
    void draw(std::size_t done, const std::string& detail, bool final_line);

    std::string label_;
    std::size_t total_;
    bool enabled_;
    bool finished_ = false;
    std::chrono::steady_clock::time_point start_;
    std::chrono::steady_clock::time_point last_draw_;
};

}  // namespace shine
