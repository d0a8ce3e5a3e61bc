// Training in the background, so that registration never waits for it (the real-time mode of
// `shine map` without poses: keyframes.max_ms_per_scan > 0, keyframe_policy.hpp).
//
// A keyframe's integration (IncrementalMapper::add_scan) runs on a thread of its own (one for the
// run), in its own TBB arena of one thread, while the caller registers the next scans against a
// snapshot: a deep copy of the map (NeuralSdf::clone) made by the training thread when its scan is
// done, so that registration reads a map nobody writes. While a scan trains, the mapper belongs to
// the training thread: the caller touches it only after wait(). A keyframe that comes while the
// trainer is busy is the caller's to defer. The caller gives each scan the budget's time: when its
// registration took less and a keyframe still trains, it waits for the training for what is left (a
// sensor's next scan would not have come yet), never longer.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/incremental_mapper.hpp"
#include "shine/model/neural_sdf.hpp"

namespace shine {

/// A scan the trainer finished: its statistics and the seconds from submit() to its snapshot.
struct TrainedScan {
    std::size_t index = 0;  ///< the caller's number for it (submit's `index`)
    IncrementalFrameStats stats;
    double seconds = 0.0;
};

class BackgroundTraining {
  public:
    /// `mapper` must outlive this object; `snapshot` starts as a copy of its map.
    explicit BackgroundTraining(IncrementalMapper& mapper);
    /// Lets the scan in training finish, then ends the thread (an error it threw is dropped:
    /// call wait() to see it).
    ~BackgroundTraining();
    BackgroundTraining(const BackgroundTraining&) = delete;
    BackgroundTraining& operator=(const BackgroundTraining&) = delete;

    /// Whether a scan is training (submit() would have to wait).
    bool busy() const { return busy_.load(std::memory_order_acquire); }
    /// Starts integrating `scan` (at its T_world_sensor) into the map, with the steps of
    /// `step_scans` scans (IncrementalMapper::add_scan). Throws std::logic_error while busy().
    /// `extra_delay` lengthens the training (a test hook, see incremental_sequence).
    void submit(std::size_t index, Scan scan, int step_scans = 1,
                std::chrono::milliseconds extra_delay = {});
    /// Waits until no scan trains; rethrows what the last one threw.
    void wait();
    /// Waits at most `seconds` for the scan in training; returns !busy() (errors wait for
    /// wait()).
    bool wait_for(double seconds);
    /// The map as the last finished scan left it.
    std::shared_ptr<const NeuralSdf> snapshot() const;
    /// The scan finished since the last call, if any (at most one: submit() needs !busy()).
    std::optional<TrainedScan> take_finished();

  private:
    struct Job {
        std::size_t index = 0;
        Scan scan;
        int step_scans = 1;
        std::chrono::milliseconds extra_delay{0};
    };
    /// The training thread: one for the object's life (per-thread state of TBB and the trainer
    /// is made once), waiting for jobs.
    void run();

    IncrementalMapper& mapper_;
    std::atomic<bool> busy_{false};
    mutable std::mutex mutex_;      ///< guards everything below
    std::condition_variable wake_;  ///< a job or the end for the thread, a finished job for wait()
    std::optional<Job> job_;
    bool stopping_ = false;
    std::shared_ptr<const NeuralSdf> snapshot_;
    std::optional<TrainedScan> finished_;
    std::exception_ptr error_;
    std::thread thread_;  ///< last: started once the members above exist
};

}  // namespace shine
