// One optimisation step of the neural SDF on rays (paper Eq. (4): L_bce + lambda_e * L_eikonal),
// with Adam on the touched feature rows and on the decoder.
//
// A batch is split into fixed chunks; each chunk draws its rays with its own random stream
// (seeded by seed, iteration and chunk) and computes its samples' gradients in parallel with TBB
// (batch_gradient.hpp: corner lookups once per sample, the decoder as matrix products over the
// chunk). The feature gradients are then reduced in parallel over a fixed partition of the
// feature rows (blocks of kRowsPerPartitionBlock consecutive rows, dealt round the partitions):
// each partition adds its rows' contributions in chunk order (partition_records.hpp) and runs the
// regulariser and Adam on its touched rows, so every row sees the same sums in the same order
// whatever the number of threads. The decoder's gradient is summed in chunk order.
// The result is therefore identical for a given seed whatever the number of threads.
//
// A float16 feature table is trained in mixed precision: the forward and backward passes read the
// float16 map, Adam updates a float32 master copy held by the Trainer, and each updated row is
// rounded back into the map, so the map is always the one that queries, baking and saving use.
//
// Adam's moments, the master copy and the regulariser's anchors are kept per row only where the
// map is being trained (feature_row_state.hpp); in incremental mode, begin_scan() marks each scan
// and release_inactive_state() drops the state of rows no recent scan touched.
#pragma once

#include <cstdint>
#include <vector>

#include "shine/core/trivial_array.hpp"
#include "shine/model/neural_sdf.hpp"
#include "shine/optim/adam.hpp"
#include "shine/optim/feature_row_state.hpp"
#include "shine/optim/importance_weights.hpp"
#include "shine/sampling/ray_sampler.hpp"
#include "shine/sampling/ray_set.hpp"

namespace shine {

class BinaryReader;
class BinaryWriter;

struct TrainerConfig {
    int batch_size = 4096;        ///< samples per iteration (rays = batch / samples per ray)
    float sigma_m = 0.05f;        ///< sigmoid scale of Eq. (1)
    float eikonal_weight = 0.1f;  ///< lambda_e, on surface samples
    bool train_decoder = true;    ///< false in incremental mode with a pretrained decoder
    AdamConfig feature_adam{};    ///< lr 0.01, betas (0.9, 0.99)
    AdamConfig decoder_adam{};
    std::uint64_t seed = 42;
    int num_chunks = 32;  ///< fixed work split (determinism does not depend on threads)
};

/// Wall-clock seconds the trainer spent, accumulated over steps (for the stage profile).
struct TrainerSeconds {
    double sample = 0.0;      ///< drawing samples along the rays
    double train = 0.0;       ///< the rest of step(): lookups, decoder, loss, reduction, Adam
    double importance = 0.0;  ///< accumulate_bce_gradient_norms()
};

/// The importance pass's result: per feature row it reached, the sum of its samples' gradient
/// norms (rows in no particular order, each once).
struct RowGradientNormSums {
    std::vector<std::int32_t> rows;
    std::vector<float> sums;
};

/// Losses of one step, averaged over the valid samples.
struct TrainStepStats {
    double bce = 0.0;
    double eikonal = 0.0;
    double regularization = 0.0;  ///< lambda_r * L_r over the touched rows (incremental mode)
    std::size_t valid_samples = 0;
    std::size_t drawn_samples = 0;
};

/// Part of a step's rays drawn from a sub-range alone: incremental mode's current scan among the
/// replayed ones (IncrementalConfig::replay_current_share).
struct RayFocus {
    std::size_t begin = 0;  ///< the focused rays are [begin, ray_end) of the step's range
    float share = 0.0f;     ///< of the step's rays, drawn from the focused range (0: none)
};

class Trainer {
  public:
    Trainer(NeuralSdf& sdf, const TrainerConfig& config, const SamplingConfig& sampling);
    ~Trainer();

    /// Call after the octree grew: sizes the optimiser state and gradient buffers.
    void on_map_grown();

    /// Keeps the anchors theta* of the importance regulariser with each row's state (incremental
    /// mode; call before the first step). Without it step() takes no regulariser.
    void enable_anchors();
    /// Starts a scan (incremental mode): a row's anchor is its value when the scan first touches
    /// it, i.e. its value at the start of the scan.
    void begin_scan() { ++scan_; }
    /// Drops the optimiser state of the rows (in pages of FeatureRowState::kRowsPerPage) that none
    /// of the last `keep_scans` scans touched. Returns the number of pages released.
    std::size_t release_inactive_state(std::uint32_t keep_scans);

    /// One iteration on rays drawn uniformly from [ray_begin, ray_end) of `rays` (rays grouped by
    /// voxel: as RayDrawer draws them, ray_draw.hpp; the range's ends and focus.begin are then
    /// scan boundaries). With a
    /// `regularizer` (incremental mode) the loss adds its lambda_r * L_r over the feature rows the
    /// batch touched (paper Eq. (5)); without one the step is exactly the batch-mode step. With a
    /// `focus` inside the range, each ray comes from [focus.begin, ray_end) with probability
    /// focus.share and from the whole range otherwise.
    TrainStepStats step(const RaySet& rays, std::size_t ray_begin, std::size_t ray_end,
                        std::uint64_t iteration, const ImportanceWeights* regularizer = nullptr,
                        const RayFocus& focus = {});

    /// The importance pass of paper Eq. (4): for every ray of [ray_begin, ray_end) once, draws its
    /// samples (from the stream importance_stream_seed(pass, ray)) and sums, per feature row,
    /// the norms |dL_bce(x_k, l_k)/dtheta_row| of each sample's BCE gradient (per sample, not
    /// averaged; no Eikonal term) into `row_sums` (replaced; only the rows reached). Returns the
    /// number of samples that fell inside the map. Changes no parameter. Deterministic for any
    /// thread count.
    /// With `ray_stride` > 1 only the rays ray_begin, ray_begin + ray_stride, ... are used (a
    /// subsample for the mean over the scan's samples; see IncrementalConfig).
    /// The streams are numbered from ray `seed_ray_origin` (ray r draws from stream r -
    /// seed_ray_origin): a set whose first rays are no longer used (ReplayRays' dead prefix)
    /// gives its rays the samples they had in a set that starts with its live rays.
    std::size_t accumulate_bce_gradient_norms(const RaySet& rays, std::size_t ray_begin,
                                              std::size_t ray_end, std::uint64_t pass,
                                              RowGradientNormSums& row_sums,
                                              std::size_t ray_stride = 1,
                                              std::size_t seed_ray_origin = 0);
    /// Seed of the random stream the importance pass samples ray `ray` of pass `pass` with.
    std::uint64_t importance_stream_seed(std::uint64_t pass, std::uint64_t ray) const;

    const TrainerConfig& config() const { return config_; }
    /// Seconds spent so far (reset with reset_seconds()).
    const TrainerSeconds& seconds() const { return seconds_; }
    void reset_seconds() { seconds_ = TrainerSeconds{}; }
    void set_feature_learning_rate(float lr) { feature_adam_.set_learning_rate(lr); }
    void set_decoder_learning_rate(float lr) { decoder_adam_.set_learning_rate(lr); }
    /// The half-width of the band the surface samples are drawn from, from the next step on.
    void set_surface_band_m(float band_m) { sampling_.surface_band_m = band_m; }
    /// Free-space samples per ray and samples per step, from the next step on; throws
    /// ConfigError if the samples per ray leave [1, kMaxSamplesPerRay] or exceed the batch.
    void set_free_samples_and_batch_size(int free_samples, int batch_size);
    std::size_t optimizer_bytes() const {
        return row_state_.memory_bytes() + decoder_adam_.memory_bytes() + local_index_.bytes();
    }
    /// Pages of per-row optimiser state currently held.
    std::size_t resident_state_pages() const { return row_state_.resident_pages(); }

    /// Everything a later step depends on besides the SDF itself (for a checkpoint): the per-row
    /// state (Adam's moments and step counts, master copy, anchors), the decoder's Adam state and
    /// the step and scan counters. load_state() expects the map to have the rows it had at
    /// save_state() (the caller rebuilds it first) and throws IoError (via the reader) where the
    /// shapes differ.
    void save_state(BinaryWriter& out) const;
    void load_state(BinaryReader& in);

    /// Fixed number of row partitions of the parallel gradient reduction.
    static constexpr int kRowPartitions = 16;
    /// Rows go to the partitions in blocks of this many consecutive rows, so that a cache line
    /// of per-row data (16 local indices, 4 float16 rows) belongs to one partition: the threads
    /// do not write to the same lines, and a partition's pass reads whole lines of its own.
    static constexpr int kRowsPerPartitionBlock = 64;
    /// The partition of feature row `row`.
    static constexpr int partition_of_row(std::int32_t row) {
        return (row / kRowsPerPartitionBlock) % kRowPartitions;
    }

  private:
    struct Chunk;
    struct Partition;

    NeuralSdf& sdf_;
    TrainerConfig config_;
    SamplingConfig sampling_;
    AdamSchedule feature_adam_;  ///< the features' Adam settings and bias corrections
    DenseAdam decoder_adam_;
    FeatureRowState row_state_;
    std::uint32_t scan_ = 0;  ///< begin_scan() calls (incremental mode; 0 in batch mode)
    /// Per feature row, its index in its partition's touched rows during a step, else -1.
    TrivialArray<std::int32_t> local_index_;  ///< per map row; grows with the map, never copied
    std::vector<float> decoder_grads_;
    std::vector<Chunk> chunks_;
    std::vector<Partition> partitions_;
    std::uint32_t steps_taken_ = 0;  ///< bounds every feature row's Adam step count
    TrainerSeconds seconds_;
};

}  // namespace shine
