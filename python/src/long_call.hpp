// Long calls from Python: run without the GIL, on the thread count asked for, and stop cleanly on
// Ctrl-C.
//
// Python's own SIGINT handler only sets a flag; the KeyboardInterrupt is raised when the
// interpreter next runs Python's signal handlers (PyErr_CheckSignals, which needs the GIL and the
// main thread). The C++ loops that can pause (BatchMapper::train) poll a SignalPoll between
// steps: it takes the GIL for a moment, runs the handlers and, if one raised, keeps the exception
// and asks the loop to stop; the binding then raises it once the loop has returned and the GIL is
// held again. Loops that cannot pause (one incremental scan, a bake) are short and are followed
// by a poll. shine::request_stop() (core/stop_request.hpp) stops the same loops, with a
// KeyboardInterrupt too.
#pragma once

#include <pybind11/pybind11.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>
#include <thread>

#include "shine/core/stop_request.hpp"

namespace shinevdb {
namespace py = pybind11;

/// Polls Python's signal handlers from code running without the GIL.
class SignalPoll {
  public:
    /// Without the GIL: true once a signal handler raised (or shine::request_stop() was called).
    /// Takes the GIL at most every kInterval, so a tight loop does not contend for it.
    bool operator()() {
        if (error_) return true;
        if (shine::stop_requested()) {
            stop_requested_ = true;
            return true;
        }
        const auto now = std::chrono::steady_clock::now();
        if (now - last_ < kInterval) return false;
        last_ = now;
        py::gil_scoped_acquire gil;
        if (PyErr_CheckSignals() != 0) error_.emplace();  // fetches the pending exception
        return error_.has_value();
    }

    /// With the GIL: raises the exception a handler raised, if any, or KeyboardInterrupt for a
    /// shine::request_stop() (whose request it then clears, so that the next call runs).
    void rethrow() {
        if (error_) {
            py::error_already_set error = std::move(*error_);
            error_.reset();
            throw error;
        }
        if (stop_requested_) {
            stop_requested_ = false;
            shine::clear_stop_request();
            PyErr_SetString(PyExc_KeyboardInterrupt, "stopped by shine::request_stop()");
            throw py::error_already_set();
        }
    }

  private:
    static constexpr std::chrono::milliseconds kInterval{20};
    std::optional<py::error_already_set> error_;
    bool stop_requested_ = false;
    std::chrono::steady_clock::time_point last_{};
};

/// With the GIL: raises KeyboardInterrupt (or what a handler raises) for a signal received while
/// it was released.
inline void check_signals() {
    if (PyErr_CheckSignals() != 0) throw py::error_already_set();
}

/// Limits TBB to `threads` workers (0: all hardware threads) while it lives, as the CLI does.
inline std::unique_ptr<tbb::global_control> limit_threads(int threads) {
    const int n =
        threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, n);
}

}  // namespace shinevdb
