// Ctrl-C for long runs: while a StopOnSignal object is alive, the first SIGINT or SIGTERM does
// not kill the process but asks it to stop; the mapping loops poll stop_requested() after every
// step, write a checkpoint and leave with shine::Interrupted. A second signal, a second or more
// after the first, restores the default action and re-raises it, so a run that does not stop soon
// enough can still be killed; a repeat within the second is taken as the same request (`timeout`
// signals the process and then its process group).
#pragma once

namespace shine {

/// True once a stop was requested (by a signal or request_stop()).
bool stop_requested();
/// Asks the running loops to stop after their current step (what the signal handler does).
void request_stop();
/// Forgets an earlier request (for a new run in the same process).
void clear_stop_request();

/// Installs the SIGINT/SIGTERM handlers for its lifetime (one at a time), restoring the previous
/// handlers when it ends.
class StopOnSignal {
  public:
    StopOnSignal();
    ~StopOnSignal();
    StopOnSignal(const StopOnSignal&) = delete;
    StopOnSignal& operator=(const StopOnSignal&) = delete;
};

}  // namespace shine
