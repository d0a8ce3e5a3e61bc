// A progress line on stderr for long loops: "label  [#####.....]  42/100  3.1 s, ETA 4 s  detail".
// The Blender add-on parses this line (blender_addon/shinevdb/map_job.py); the ETA part is
// optional there, and is left out until the estimate is stable.
#pragma once

#include <chrono>
#include <cstddef>
#include <optional>
#include <string>

namespace shine {

/// Seconds left in a stage of `total` steps, at the rate measured since the first finished step
/// (`first_done` steps at `first_seconds`): the first step often carries a stage's setup, so a
/// rate that includes it overstates the rest. Empty until at least 5 % of the steps and 1 s have
/// passed since that first step, when the rate is not yet a stable estimate.
std::optional<double> progress_eta_seconds(std::size_t first_done, double first_seconds,
                                           std::size_t done, double seconds, std::size_t total);

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
    std::optional<std::size_t> first_done_;  ///< steps done at the first update, its time below
    double first_seconds_ = 0.0;
    int last_decile_ = -1;  ///< in a log file, the tenth of the work last printed
};

}  // namespace shine
