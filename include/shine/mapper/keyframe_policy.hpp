// Tracking decoupled from mapping (`shine map --mode incremental` without poses): every scan is
// registered to the map, but only the scans that add something train it at once (keyframes). The
// others are deferred: kept by index, and caught up after the last scan (integrated untrained,
// then trained together by the consolidation), so that the final map has every scan's rays while
// the run spends its per-scan time on registration.
//
// A registered scan is a keyframe when
//   - it is the first, or the map is still in its ICP warm-up, or no registration to the map was
//     accepted (its pose is not the map's word: the map learns where it is);
//   - the map covers less than min_coverage of its registration points (valid / all: a point
//     outside the allocated map has no residual): new ground;
//   - the sensor moved min_translation_m or turned min_rotation_deg since the last keyframe;
//   - max_interval_scans scans went by since the last keyframe.
// With a budget (max_ms_per_scan > 0) the policy keeps an account: each scan brings the budget
// and costs its wall time; a keyframe trains only when the account holds the training time the
// last keyframes took, else it is deferred (reason kBudget). Registration is never skipped; a scan
// whose coverage is below forced_coverage trains whatever the account holds (the map must grow
// for the tracking to follow), and so may overrun the budget. With a budget the keyframes train in
// the background (background_training.hpp) and registration never waits for them: a keyframe that
// comes while an earlier one still trains is deferred (kBusy), and the account only pays for the
// caller's own time (registration), which training on the other thread may slow down.
#pragma once

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <deque>

namespace shine {

class BinaryReader;
class BinaryWriter;
struct OdometryRecord;

struct KeyframeConfig {
    /// false: every scan trains the map when it comes (as before keyframes).
    bool enabled = true;
    /// A drive at 10 m/s and 10 Hz trains every 4th scan; the walk (1.7 m between scans, turning)
    /// about three in four. Measured without poses against training every scan: the street's
    /// F-score 96.33 against 96.38 %, the walk's ATE 5.39 cm either way, the real drive's median
    /// time a scan 118 against 222 ms (docs/realtime.md).
    double min_translation_m = 4.0;
    double min_rotation_deg = 15.0;
    int max_interval_scans = 4;
    /// A scan of which the map covers less is new ground. Far points lie outside the map on
    /// every drive (0.85-0.95 of a drive's points are covered from one scan to the next); on
    /// the street with sweep distortion, 0.77 three metres on, where 0.75 let the next scan
    /// register 34 cm off (docs/realtime.md).
    double min_coverage = 0.8;
    /// A keyframe also takes the training steps of the scans deferred as redundant since the
    /// one before it (one cosine decay over them all), so that the online map that the next
    /// scans register to is trained as when every scan trains; the consolidation still takes
    /// the deferred scans' steps over all kept scans. 100-scan simulated streets without poses
    /// (seeds 7 / 21): F-score in the data's frame 91.10 / 88.04 -> 94.44 / 94.46 %, position
    /// error without alignment 4.0 / 4.5 -> 2.1 / 1.9 cm; held-out rays within 10 cm over 7
    /// splits at the data's poses, on average, walk +0.33 and drive -0.17 points
    /// (docs/realtime.md). false: a keyframe trains the steps of one scan.
    bool keyframe_takes_deferred_steps = true;
    /// Wall-clock milliseconds a scan may take on average (0: no budget).
    double max_ms_per_scan = 0.0;
    /// The account never holds more than this many scans' budget (time saved long ago does not
    /// pay for a burst of training now).
    double max_saved_scans = 5.0;
    /// Below this coverage a keyframe trains even over the budget.
    double forced_coverage = 0.5;
    /// Deferred scans kept for the catch-up; beyond, the oldest is dropped (skipped).
    int max_deferred_scans = 1000;
};

/// Why a scan was trained or deferred.
enum class KeyframeReason : std::uint8_t {
    kDisabled,   ///< keyframes off: every scan trains
    kFirst,      ///< the first scan
    kWarmup,     ///< registered by ICP (the map is young) or not registered to the map
    kCoverage,   ///< the map covers too little of it
    kMotion,     ///< moved or turned enough since the last keyframe
    kInterval,   ///< max_interval_scans since the last keyframe
    kRedundant,  ///< deferred: the map covers it and it is close to the last keyframe
    kBudget,     ///< deferred: a keyframe, but the account cannot pay for its training
    kBusy        ///< deferred: a keyframe, but the background trainer is still busy
};
const char* to_string(KeyframeReason reason);

struct KeyframeChoice {
    bool train = true;
    KeyframeReason reason = KeyframeReason::kDisabled;
};

/// What the policy did over a run (stats.json "keyframes").
struct KeyframeCounts {
    std::size_t trained = 0;      ///< trained when they came
    std::size_t deferred = 0;     ///< deferred (caught up at the end, or skipped)
    std::size_t over_budget = 0;  ///< of the deferred: keyframes the budget deferred
    std::size_t busy = 0;         ///< of the deferred: keyframes that found the trainer busy
    std::size_t skipped = 0;      ///< deferred ones dropped from a full backlog, or never caught up
    std::size_t caught_up = 0;    ///< deferred ones integrated after the last scan
};

class KeyframePolicy {
  public:
    /// Throws ConfigError naming the keyframes.* key of an invalid setting.
    explicit KeyframePolicy(const KeyframeConfig& config);

    /// The choice for the next scan, registered with `record` at `T_world_sensor`.
    KeyframeChoice choose(const OdometryRecord& record,
                          const Eigen::Isometry3d& T_world_sensor) const;
    /// After the scan: what was chosen, its pose, its wall time (load to end of mapping) and, if
    /// trained, the seconds its training took (the account's estimate of the next one).
    void record(const KeyframeChoice& choice, const Eigen::Isometry3d& T_world_sensor,
                double wall_seconds, double train_seconds);

    const KeyframeConfig& config() const { return config_; }
    const KeyframeCounts& counts() const { return counts_; }
    KeyframeCounts& counts() { return counts_; }
    /// The account's balance in seconds (budget runs only).
    double saved_seconds() const { return saved_s_; }

    /// For checkpoints.
    void save(BinaryWriter& out) const;
    void load(BinaryReader& in);

  private:
    /// The training seconds of the recent keyframes' median (0 before the first).
    double expected_train_seconds() const;

    KeyframeConfig config_;
    KeyframeCounts counts_;
    bool has_keyframe_ = false;
    Eigen::Isometry3d last_keyframe_ = Eigen::Isometry3d::Identity();
    int since_keyframe_ = 0;
    double saved_s_ = 0.0;
    std::deque<double> train_seconds_;  ///< the last few keyframes'
};

}  // namespace shine
