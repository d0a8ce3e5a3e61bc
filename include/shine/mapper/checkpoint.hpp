// Checkpoints of interrupted mapping runs: Ctrl-C (SIGINT) or SIGTERM during `shine map` finishes
// the current step (a frame in incremental mode, a scan or an optimisation step in batch mode),
// writes OUT/checkpoint.bin and exits; `shine map --resume OUT` continues to the result the
// uninterrupted run would have given, bit for bit (the run is deterministic for a seed, whatever
// the thread count).
//
// The file is written atomically and holds, in order:
//   "SHINE-CHECKPOINT", format version, a byte-order mark,
//   the run description (the caller's text: for the CLI, JSON with the data, frame selection and
//   configuration, so that --resume needs no other argument),
//   the mode, then the mode's sections (map_sequence.cpp, incremental_sequence.cpp).
// The map's structure is not stored: resuming reads the scans that were integrated again and
// rebuilds the octree exactly (allocation is deterministic), then loads the feature rows, the
// decoder and the optimiser state, which are indexed by feature row. That keeps the file at the
// size of the parameters and their optimiser state, and checks on the way that the data did not
// change (every scan's point count is compared).
#pragma once

#include <chrono>
#include <filesystem>
#include <functional>
#include <string>

#include "shine/io/binary_stream.hpp"
#include "shine/model/neural_sdf.hpp"

namespace shine {

/// How a sequence-mapping run may stop early and continue later.
struct RunControl {
    /// Where checkpoints are written and, with `resume`, read (empty: never written).
    std::filesystem::path checkpoint_path;
    /// Stored in every checkpoint (what the caller needs to continue the run).
    std::string run_description;
    /// Also write a checkpoint every this many seconds of mapping (0: only when stopping).
    double checkpoint_interval_s = 0.0;
    /// Continue from the checkpoint at checkpoint_path.
    bool resume = false;
    /// Polled after every step; true stops the run with a checkpoint (shine::Interrupted).
    std::function<bool()> stop_requested;
    /// The command that continues the run, quoted in the Interrupted message.
    std::string resume_hint;
};

/// The mode a checkpoint belongs to.
enum class CheckpointMode : std::uint8_t { kBatch = 1, kIncremental = 2 };

/// Writes a checkpoint atomically: the header, `run_description`, `mode`, then what `write_state`
/// writes. Throws IoError naming the file if it cannot be written.
void write_checkpoint(const std::filesystem::path& path, const std::string& run_description,
                      CheckpointMode mode, const std::function<void(BinaryWriter&)>& write_state);

/// Opens a checkpoint and reads its header; `run_description` and `mode` receive the stored
/// values and the returned reader stands at the mode's sections. Throws IoError naming the file
/// for a missing, truncated or foreign file.
BinaryReader read_checkpoint_header(const std::filesystem::path& path, std::string& run_description,
                                    CheckpointMode& mode);

/// The run description alone (for `shine map --resume` to rebuild its options).
std::string read_checkpoint_description(const std::filesystem::path& path);

/// Throws shine::Interrupted "stopped <where>; checkpoint written to <path>; continue with
/// `<resume_hint>`" once a run has written its checkpoint.
[[noreturn]] void throw_stopped_with_checkpoint(const RunControl& control,
                                                const std::string& where);

/// The SDF's parameters: feature rows (in the map's precision), decoder weights and the map
/// origin, with the octree's row counts per level so that loading into a rebuilt octree that
/// differs fails with a message instead of mixing up rows.
void save_sdf_parameters(BinaryWriter& out, const NeuralSdf& sdf);
void load_sdf_parameters(BinaryReader& in, NeuralSdf& sdf);

/// When a periodic checkpoint is due (RunControl::checkpoint_interval_s).
class CheckpointClock {
  public:
    explicit CheckpointClock(double interval_s) : interval_s_(interval_s) {}
    bool due() const {
        return interval_s_ > 0.0 &&
               std::chrono::duration<double>(std::chrono::steady_clock::now() - last_).count() >=
                   interval_s_;
    }
    void reset() { last_ = std::chrono::steady_clock::now(); }

  private:
    double interval_s_;
    std::chrono::steady_clock::time_point last_ = std::chrono::steady_clock::now();
};

}  // namespace shine
