#include "shine/mapper/background_training.hpp"

#include <tbb/task_arena.h>

#include <stdexcept>
#include <utility>

namespace shine {

BackgroundTraining::BackgroundTraining(IncrementalMapper& mapper)
    : mapper_(mapper),
      snapshot_(std::make_shared<NeuralSdf>(mapper.sdf().clone())),
      thread_([this] { run(); }) {}

BackgroundTraining::~BackgroundTraining() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stopping_ = true;
    }
    wake_.notify_all();
    thread_.join();
}

void BackgroundTraining::submit(std::size_t index, Scan scan, int step_scans,
                                std::chrono::milliseconds extra_delay) {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        if (busy_.load(std::memory_order_acquire)) {
            throw std::logic_error("BackgroundTraining::submit while a scan trains");
        }
        job_ = Job{index, std::move(scan), step_scans, extra_delay};
        busy_.store(true, std::memory_order_release);
    }
    wake_.notify_all();
}

void BackgroundTraining::run() {
    // One thread of its own: the caller's registration keeps the default arena's threads.
    tbb::task_arena arena(1);
    for (;;) {
        Job job;
        {
            std::unique_lock<std::mutex> lock(mutex_);
            wake_.wait(lock, [&] { return stopping_ || job_.has_value(); });
            if (!job_) return;  // stopping, nothing left to train
            job = std::move(*job_);
            job_.reset();
        }
        const auto start = std::chrono::steady_clock::now();
        TrainedScan done;
        done.index = job.index;
        std::exception_ptr error;
        std::shared_ptr<const NeuralSdf> snapshot;
        try {
            arena.execute([&] {
                done.stats = mapper_.add_scan(job.scan, job.step_scans);
                if (job.extra_delay.count() > 0) std::this_thread::sleep_for(job.extra_delay);
                snapshot = std::make_shared<NeuralSdf>(mapper_.sdf().clone());
            });
        } catch (...) {
            error = std::current_exception();
        }
        done.seconds =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        {
            std::lock_guard<std::mutex> lock(mutex_);
            if (error) {
                error_ = error;
            } else {
                snapshot_ = std::move(snapshot);
                finished_ = std::move(done);
            }
            busy_.store(false, std::memory_order_release);
        }
        wake_.notify_all();
    }
}

void BackgroundTraining::wait() {
    std::unique_lock<std::mutex> lock(mutex_);
    wake_.wait(lock, [&] { return !busy_.load(std::memory_order_acquire); });
    if (error_) {
        std::exception_ptr error = error_;
        error_ = nullptr;
        std::rethrow_exception(error);
    }
}

bool BackgroundTraining::wait_for(double seconds) {
    std::unique_lock<std::mutex> lock(mutex_);
    return wake_.wait_for(lock, std::chrono::duration<double>(seconds),
                          [&] { return !busy_.load(std::memory_order_acquire); });
}

std::shared_ptr<const NeuralSdf> BackgroundTraining::snapshot() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return snapshot_;
}

std::optional<TrainedScan> BackgroundTraining::take_finished() {
    std::lock_guard<std::mutex> lock(mutex_);
    std::optional<TrainedScan> out = std::move(finished_);
    finished_.reset();
    return out;
}

}  // namespace shine
