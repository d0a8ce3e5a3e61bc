#include "shine/core/progress.hpp"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cstdio>

namespace shine {
namespace {
std::atomic<bool> g_enabled{true};
}

std::optional<double> progress_eta_seconds(std::size_t first_done, double first_seconds,
                                           std::size_t done, double seconds, std::size_t total) {
    constexpr double kMinShare = 0.05;   // of the stage's steps since the first one
    constexpr double kMinSeconds = 1.0;  // since the first step
    if (done <= first_done || done >= total) return std::nullopt;
    const double steps = static_cast<double>(done - first_done);
    const double elapsed = seconds - first_seconds;
    if (steps < kMinShare * static_cast<double>(total) || elapsed < kMinSeconds) {
        return std::nullopt;
    }
    return elapsed / steps * static_cast<double>(total - done);
}

void Progress::set_globally_enabled(bool enabled) { g_enabled = enabled; }

Progress::Progress(std::string label, std::size_t total, bool enabled)
    : label_(std::move(label)),
      total_(std::max<std::size_t>(total, 1)),
      enabled_(enabled && g_enabled),
      start_(std::chrono::steady_clock::now()),
      last_draw_(start_ - std::chrono::seconds(1)) {}

Progress::~Progress() {
    if (!finished_ && enabled_) std::fputc('\n', stderr);
}

void Progress::update(std::size_t done, const std::string& detail) {
    if (!enabled_) return;
    const auto now = std::chrono::steady_clock::now();
    if (!first_done_ && done > 0) {
        first_done_ = done;
        first_seconds_ = std::chrono::duration<double>(now - start_).count();
    }
    if (now - last_draw_ < std::chrono::milliseconds(100) && done < total_) return;
    last_draw_ = now;
    draw(done, detail, false);
}

void Progress::finish(const std::string& detail) {
    if (!enabled_ || finished_) return;
    draw(total_, detail, true);
    finished_ = true;
}

void Progress::draw(std::size_t done, const std::string& detail, bool final_line) {
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const double fraction = std::min(1.0, static_cast<double>(done) / static_cast<double>(total_));
    constexpr int kWidth = 24;
    const int filled = static_cast<int>(fraction * kWidth);
    char bar[kWidth + 1];
    for (int i = 0; i < kWidth; ++i) bar[i] = i < filled ? '#' : '.';
    bar[kWidth] = '\0';
    const std::optional<double> eta =
        final_line || !first_done_
            ? std::nullopt
            : progress_eta_seconds(*first_done_, first_seconds_, done, seconds, total_);
    // On a terminal the line is redrawn in place; in a log file each update is its own line.
    const bool tty = ::isatty(STDERR_FILENO);
    if (!tty && !final_line && done != 0 && fraction < 1.0) {
        // Keep logs short: only about every tenth of the work.
        const int decile = static_cast<int>(fraction * 10);
        if (decile == last_decile_) return;
        last_decile_ = decile;
    }
    const std::string eta_text =
        eta ? ", ETA " + std::to_string(static_cast<long long>(*eta + 0.5)) + " s" : "";
    std::fprintf(stderr, "%s%-10s [%s] %zu/%zu  %.1f s%s%s", tty ? "\r\033[K" : "", label_.c_str(),
                 bar, std::min(done, total_), total_, seconds, eta_text.c_str(),
                 detail.empty() ? "" : ("  " + detail).c_str());
    if (final_line || !tty) std::fputc('\n', stderr);
    std::fflush(stderr);
}

}  // namespace shine
