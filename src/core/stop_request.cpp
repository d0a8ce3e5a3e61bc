#include "shine/core/stop_request.hpp"

#include <unistd.h>

#include <atomic>
#include <csignal>
#include <ctime>

namespace shine {
namespace {

std::atomic<bool> g_stop_requested{false};
/// When the first signal arrived (CLOCK_MONOTONIC, ns).
std::atomic<long long> g_first_signal_ns{0};
/// A repeat within this time is the same request: `timeout` and process managers send a signal
/// to the process and then to its process group, so one request can arrive twice.
constexpr long long kRepeatGapNs = 1'000'000'000;

long long monotonic_ns() {
    timespec ts{};
    ::clock_gettime(CLOCK_MONOTONIC, &ts);  // async-signal-safe
    return static_cast<long long>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}
static_assert(std::atomic<bool>::is_always_lock_free, "the signal handler needs a lock-free flag");

struct sigaction g_previous_int;
struct sigaction g_previous_term;

void on_signal(int signal_number) {
    const long long now = monotonic_ns();
    if (g_stop_requested.exchange(true)) {
        if (now - g_first_signal_ns.load() < kRepeatGapNs) return;
        // Second signal: the user insists; die as the signal's default action does.
        ::signal(signal_number, SIG_DFL);
        ::raise(signal_number);
        return;
    }
    g_first_signal_ns.store(now);
    // Only async-signal-safe calls here: write(2), no stdio.
    static const char kMessage[] =
        "\nshine: stopping after the current step to write a checkpoint "
        "(send the signal again to quit at once, without one)\n";
    const ssize_t ignored = ::write(STDERR_FILENO, kMessage, sizeof(kMessage) - 1);
    (void)ignored;
}

}  // namespace

bool stop_requested() { return g_stop_requested.load(std::memory_order_relaxed); }
void request_stop() { g_stop_requested.store(true); }
void clear_stop_request() { g_stop_requested.store(false); }

StopOnSignal::StopOnSignal() {
    struct sigaction action {};
    action.sa_handler = on_signal;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESTART;
    ::sigaction(SIGINT, &action, &g_previous_int);
    ::sigaction(SIGTERM, &action, &g_previous_term);
}

StopOnSignal::~StopOnSignal() {
    ::sigaction(SIGINT, &g_previous_int, nullptr);
    ::sigaction(SIGTERM, &g_previous_term, nullptr);
}

}  // namespace shine
