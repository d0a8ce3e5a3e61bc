// Incremental mapping without forgetting (paper Sec. III, "Incremental Mapping Without
// Forgetting"): scans arrive one by one; each trains the map with its own rays (and, with
// incremental.replay_frames > 1, those of the scans just before it).
//
// Per scan (add_scan):
//   1. preprocess it and move it into the map frame (the first scan fixes the map origin);
//   2. with the dynamic-point filter (config.dynamic, free_space_votes.hpp): drop the scan's points
//      that the last dynamic.vote_frames scans saw through (only the past votes here, so a
//      parked car seen first is kept), and drop the points of the normal window's earlier scans
//      that this scan sees through, so that they are not trained again;
//      then grow the octree around its points (new rows: Omega = 0);
//   3. estimate its endpoint normals among its own and the last normal_window_frames scans'
//      endpoints;
//   4. run incremental.iterations_per_frame steps on rays drawn from this scan, or with
//      replay_frames K > 1 from the last K scans (a replay_current_share of each step's rays from
//      this scan alone; the earlier scans with the normals they got when current), surface band
//      incremental.surface_band_m, learning rate decaying over the scan's steps, the loss adding
//      lambda_r * sum Omega_i |theta_i - theta*_i|^2 over the rows used (Eq. (5));
//   5. with lambda_r > 0: one pass over the scan's samples (each ray once) adds
//      (1/N) sum_k |dL_bce/dtheta_i| to Omega_i (capped at Omega_m, Eq. (4); N = the pass's
//      sample count, see importance_weights.hpp); the anchors theta* are the rows' values when
//      the next scan first touches them (the trainer snapshots them); then the optimiser state
//      of rows no frame of the last incremental.active_frames trained is released.
// start_from() continues a saved map instead of an empty one (`shine map --from`,
// docs/continue.md): the old rows start at the importance cap, the old decoder stays frozen.
// The decoder is pretrained and frozen (models/decoder_pretrained.yaml by default); Adam's state
// and the importance weights persist across scans. Deterministic for a seed, whatever the
// thread count.
#pragma once

#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/batch_mapper.hpp"
#include "shine/mapper/mapper_config.hpp"
#include "shine/mapper/pose_refinement.hpp"
#include "shine/mapper/replay_rays.hpp"
#include "shine/mapper/scan_in_map.hpp"
#include "shine/mapper/stage_profile.hpp"
#include "shine/model/decoder.hpp"
#include "shine/model/neural_sdf.hpp"
#include "shine/optim/importance_weights.hpp"
#include "shine/sampling/free_space_votes.hpp"
#include "shine/sampling/range_image.hpp"
#include "shine/sampling/ray_set.hpp"

namespace shine {

class BinaryReader;
class BinaryWriter;
class Trainer;

/// What one add_scan() did and how long each step took (wall-clock seconds).
struct IncrementalFrameStats {
    std::size_t rays = 0;         ///< points of the scan after preprocessing (dynamic ones too)
    std::size_t new_corners = 0;  ///< feature rows the scan added
    std::size_t rays_with_normal = 0;
    /// Points the dynamic-point filter dropped: of this scan, and of the window's earlier scans
    /// because this scan saw through them.
    std::size_t dynamic_dropped = 0;
    std::size_t dynamic_forgotten = 0;
    double preprocess_seconds = 0.0;
    double allocate_seconds = 0.0;
    double normals_seconds = 0.0;
    double train_seconds = 0.0;       ///< the scan's optimisation steps, sampling included
    double importance_seconds = 0.0;  ///< includes releasing inactive optimiser state
    double total_seconds = 0.0;
    std::size_t optimizer_bytes = 0;  ///< the trainer's state after the frame
    /// The same split by profile stage (preprocess ... importance; load is the caller's).
    StageSeconds stages;
    /// false: a deferred scan caught up by add_scan_untrained() (no steps of its own).
    bool trained = true;
    double bce = 0.0;             ///< last iteration's mean BCE
    double regularization = 0.0;  ///< last iteration's lambda_r * L_r
};

/// What IncrementalMapper::consolidate() did.
struct ConsolidationStats {
    int steps = 0;          ///< steps run (0: none)
    std::size_t scans = 0;  ///< kept scans the steps drew from
    std::size_t rays = 0;   ///< their rays
    /// The voxels the rays are grouped in (preprocess.voxel_points all: every point of the kept
    /// scans); equal to rays when each ray is its own.
    std::size_t voxels = 0;
    double seconds = 0.0;  ///< wall-clock
    double bce = 0.0;      ///< the last step's mean BCE
    float surface_band_m = 0.0f;
    int free_samples = 0;  ///< free-space samples per ray
    int batch_size = 0;    ///< samples per step
    /// Points of the kept scans that their votes on each other made dynamic before the steps
    /// (IncrementalMapper::vote_among_kept_scans), and the seconds the votes took.
    std::size_t dynamic_dropped = 0;
    double vote_seconds = 0.0;
    /// With pose refinement (consolidate()'s `refine`): what each round did, and each kept
    /// scan's correction in the map frame (T_new_old: the scan's rays were moved by it), oldest
    /// first. The kept scans are the last corrections_map.size() scans the mapper integrated
    /// (add_scan, add_scan_untrained, replay_scan, in their order). Empty without refinement.
    std::vector<PoseRefinementRound> refinement;
    std::vector<Eigen::Isometry3d> corrections_map;
};

/// The decoder incremental mode uses for `config`: config.incremental.decoder_weights resolved
/// ("builtin", a file, or "none" for the random initial decoder). Throws ConfigError if the
/// weights' shape differs from config.decoder (naming both shapes and the fix) and IoError for an
/// unreadable file.
Decoder load_incremental_decoder(const MapperConfig& config);

/// Incremental mode's defaults for outdoor leaves finer than the street's 0.2 m
/// (MapperConfig::fine_outdoor_leaf()), each unless its key is set:
/// - 15 steps per scan instead of 11 (incremental.iterations_per_frame), for a map with about
///   four times the feature rows;
/// - normals over the 0.2 m map's neighbourhood: sampling.normal_radius_m 1 m (not halved with
///   the leaf) and 24 neighbours (incremental.normal_neighbors) among the denser points;
/// - the consolidation at the end: 2000 steps (incremental.consolidation_steps) at learning rate
///   0.005 (incremental.consolidation_learning_rate), on every point of the kept scans grouped
///   by voxel (preprocess.voxel_points all; the scans' own steps train on one point per voxel),
///   30 % of its rays drawn over the points (sampling.every_point_share).
/// With the decoder pretrained at 0.1 m the 0.1 m map then scores above the 0.2 m one on the
/// real walk (85.82 / 84.82 % of the held-out rays within 10 cm with every 3rd / 2nd scan held
/// out, against 84.86 / 84.18 %) and on the streets (94.97 / 94.57 / 94.88 against 94.08 / 93.25
/// / 94.07 %) (docs/incremental.md).
void apply_incremental_defaults(MapperConfig& config);

class IncrementalMapper {
  public:
    /// Loads the decoder (load_incremental_decoder) and freezes it unless decoder_weights is
    /// "none". Throws what that throws and ConfigError for invalid settings.
    explicit IncrementalMapper(const MapperConfig& config);
    ~IncrementalMapper();

    /// Continues the saved map `old` (`shine map --from`): its feature octree, decoder and origin
    /// replace this mapper's, the origin counts as set (the scans' world poses are in the old
    /// map's world frame), the decoder stays frozen, and every old row starts with the importance
    /// cap Omega_m, so that the anchors (each row's value when a scan first touches it) hold the
    /// old part while the rows the new scans add are free. Call before the first scan. `source`
    /// (the map's file) names it in errors and becomes incremental.decoder_weights. Throws
    /// ConfigError naming `source` and the setting (map.leaf_size_m, map.num_levels,
    /// map.feature_dim, map.feature_precision, map.interpolation, decoder.hidden_dims) where the
    /// old map differs from this configuration, or Error after a scan. The consolidation then
    /// starts from the old rows' saved values (restore_old_rows()) and holds them at the cap;
    /// the saved values are kept until release_training_state() (feature_dim floats a row).
    /// A continued mapper writes no checkpoint (save_state() throws Error).
    void start_from(NeuralSdf&& old, const std::string& source);

    /// Viewpoints of the drive a continued map was made from (start_from), each a range image of
    /// the old surface seen from one of its sensor poses (map frame). At the consolidation they
    /// vote on the kept scans' points as the kept scans vote on each other
    /// (vote_among_kept_scans: compact objects only): as a near scan for a kept scan when the
    /// viewpoint is no farther from it than its own near scans (vote_frames) are, else as a far
    /// one. So a mover of the new drive standing where the old drive saw through is dropped, as a
    /// map of both drives at once drops it. Needs the end votes (keeps_scan_images()); ignored
    /// without them.
    void add_old_viewpoints(std::vector<std::pair<Eigen::Isometry3f, RangeImage>> viewpoints);
    /// Whether the kept scans vote on each other before the consolidation (dynamic filter on, far
    /// votes configured: far_vote_frames > vote_frames, objects dropped whole:
    /// objects.min_dynamic_share > 0, and consolidation steps to run).
    bool keeps_scan_images() const;

    /// Integrates one scan (steps 1-5 of the file comment). Throws DataError naming the scan's
    /// source for invalid points (per preprocess config). `step_scans`: step 4 runs the steps of
    /// that many scans (incremental.iterations_per_frame each, one cosine decay over them all):
    /// a keyframe takes the steps of the scans deferred since the one before it.
    const IncrementalFrameStats& add_scan(const Scan& scan, int step_scans = 1);

    /// Resuming a checkpoint: steps 1-2 only (preprocess, grow the map, keep the scan in the
    /// window; with replay, its normals as well), which rebuild the map's structure and window as
    /// add_scan() left them. Call
    /// it for each scan the checkpoint had integrated, then load_state().
    void replay_scan(const Scan& scan);

    /// A scan deferred by the keyframe policy (keyframe_policy.hpp), after the last scan: steps
    /// 1-3 (preprocess, grow the map, normals) without steps or importance; its rays join the
    /// kept scans, which consolidate() trains. frames() gets its statistics (trained false).
    const IncrementalFrameStats& add_scan_untrained(const Scan& scan);

    /// The end of a sequence: `steps` (incremental.consolidation_steps in `shine map`) more
    /// steps over the kept scans (the last replay_frames, with the normals each got when
    /// current), their rays drawn uniformly (with preprocess.voxel_points all: every point of
    /// each kept scan, drawn as batch mode draws grouped rays, each with its voxel's normal),
    /// with sampling.surface_band_m (batch mode's band), without the regulariser (a continued
    /// map, start_from(): its old rows restored to their saved values and held at the cap), the
    /// learning rate decaying from incremental.consolidation_learning_rate (cosine, to
    /// final_learning_rate_ratio of it). The decoder stays frozen; the optimiser starts afresh
    /// (every row's Adam state is dropped). `progress(done, total)` is called after each step when
    /// given. add_scan() may follow (the next scan's anchors are the consolidated rows); the
    /// frames' statistics are unchanged. Throws ConfigError for negative `steps`.
    ///
    /// With `refine` (rounds > 0, lengths for this map's leaf: MapperConfig::scaled_refinement) and
    /// at least 3 kept scans, the kept scans' poses are refined with the map as batch mode
    /// refines them (pose_refinement.hpp), in place: before step refine->round_step(r, steps) of
    /// round r every kept scan is registered to the map as it stands, from where its rays are
    /// (the sensor's origin, map axes), the corrections gauge-aligned to the kept scans' places
    /// before the round, and its rays moved; the steps go on with the moved rays. The kept scans
    /// in the window move with them (a later add_scan() replays them where they were refined).
    /// The consolidation's statistics give the rounds and each kept scan's correction.
    const ConsolidationStats& consolidate(int steps,
                                          const std::function<void(int, int)>& progress = {},
                                          const PoseRefinementConfig* refine = nullptr);
    /// The last consolidate()'s statistics (steps 0 before).
    const ConsolidationStats& consolidation() const { return consolidation_; }

    /// The state after the last add_scan() (parameters, optimiser, importance, iteration, frame
    /// statistics) for a checkpoint. load_state() checks that the replayed scans match the
    /// stored ones (count and points per scan) and throws IoError via the reader otherwise.
    void save_state(BinaryWriter& out) const;
    void load_state(BinaryReader& in);

    /// Feature rows of the map start_from() continued (0 without one): rows below it are the old
    /// map's.
    std::size_t start_rows() const { return start_rows_; }

    const NeuralSdf& sdf() const { return *sdf_; }
    NeuralSdf& sdf() { return *sdf_; }
    const MapperConfig& config() const { return config_; }
    /// Totals in the batch mapper's form (for stats.json).
    const MappingStats& stats() const { return stats_; }
    const std::vector<IncrementalFrameStats>& frames() const { return frames_; }
    const ImportanceWeights& importance() const { return importance_; }
    /// Median of the trained frames' total_seconds (0 before the first frame).
    double median_frame_seconds() const;
    /// Bytes of the state beyond the map: importance weights, anchors, Adam moments; after
    /// release_training_state(), what they were just before.
    std::size_t state_bytes() const;

    /// The map is final: frees the optimiser state, the importance weights and the scans of the
    /// normal window, so that the products (bake, mesh) of a long drive have that memory.
    /// sdf(), stats(), frames() and state_bytes() stay; add_scan(), replay_scan(), save_state()
    /// and load_state() throw Error afterwards.
    void release_training_state();

  private:
    /// Steps 1-2 of add_scan(): fills frame.rays, new_corners, dynamic counts, preprocess and
    /// allocate seconds.
    void preprocess_and_allocate(const Scan& scan, IncrementalFrameStats& frame);
    /// Step 2's filter: drops `current`'s dynamic points and the window's points it sees through;
    /// returns the votes of `current`'s kept points.
    /// `current_members` (or null): every point of the current scan, one voxel run per point of
    /// `current`; its runs are dropped with their leads (as window_members_'s are).
    std::vector<FreeSpaceVotes> drop_dynamic_points(const Scan& scan, ScanInMap& current,
                                                    ScanInMap* current_members,
                                                    IncrementalFrameStats& frame);
    /// Before the consolidation: every kept scan's points are voted on by the other kept scans'
    /// range images, from both sides, near (vote_frames) and far (up to far_vote_frames), as batch
    /// mode's votes are. Of the points those votes make dynamic, those of compact objects are
    /// dropped (their objects whole, voxel groups with their leads); ground and structures keep
    /// theirs, since far viewpoints see them at grazing angles. With dynamic.motion, the points
    /// of the kept scans' moving objects (moving_objects.hpp) are dropped too. Releases the
    /// scans' range images (and hands the heap's free pages back) after the votes, in any case.
    /// Returns the points dropped.
    std::size_t vote_among_kept_scans();
    /// True when the window keeps every point of its scans (preprocess.voxel_points all, with
    /// thinning on): window_members_.
    bool keeps_voxel_members() const;
    /// The consolidation's rays with window_members_: every point of the last replay_frames
    /// scans, grouped by voxel, each with its voxel lead's normal.
    RaySet kept_scans_every_point() const;
    /// Step 3: estimates the current scan's normals among the last normal_window_frames scans
    /// and stores them for replay; fills frame.rays_with_normal and normals_seconds.
    void estimate_current_normals(IncrementalFrameStats& frame);
    /// The training rays (replay_): the last replay_frames scans of the window with their stored
    /// normals, the current one last; the last `changed_scans` of them taken anew.
    void sync_replay_rays(std::size_t changed_scans);
    /// The consolidation of a continued map: the rows start_from() brought take their saved
    /// values again (the optimiser holds no state for them then), so that the consolidation's
    /// anchors are the old map's values and not where the new scans' steps moved them, one
    /// re-anchored scan after another. No-op without start_from().
    void restore_old_rows();
    /// Moves the window's last corrections.size() scans (points, origins, normals, and their
    /// every-point members) by corrections[k] (map frame, T_new_old), and forgets the training
    /// rays so that the next sync assembles them from the moved scans.
    void move_kept_scans(const std::vector<Eigen::Isometry3d>& corrections);
    /// Importance weights over the map's rows with the rows start_from() brought (below
    /// start_rows_) at incremental.old_rows_importance (at most the cap Omega_m) and the others
    /// at 0.
    ImportanceWeights importance_held_old_rows() const;
    /// Throws Error naming `what` once release_training_state() has run.
    void require_training_state(const char* what) const;

    MapperConfig config_;
    std::unique_ptr<NeuralSdf> sdf_;
    std::unique_ptr<Trainer> trainer_;
    ImportanceWeights importance_;
    /// The last max(normal_window_frames, replay_frames) scans, the current one last.
    std::deque<ScanInMap> window_;
    /// With keeps_voxel_members(): every point of window_'s scans, grouped by voxel, where run i
    /// of window_members_[w] is the voxel whose lead (the point thinning keeps) is
    /// window_[w].points_map[i]. Only the consolidation trains on them. Empty otherwise.
    std::deque<ScanInMap> window_members_;
    std::uint64_t window_first_serial_ = 0;  ///< the scan number of window_.front()
    ReplayRays replay_;                      ///< the training rays, kept from scan to scan
    /// The endpoint normals of window_'s scans, each estimated when its scan was the current one
    /// (empty with normals disabled).
    std::deque<std::vector<Eigen::Vector3f>> window_normals_;
    /// The votes window_'s points have received from the scans after them.
    std::deque<std::vector<FreeSpaceVotes>> window_votes_;
    /// The compact objects of window_'s scans, found when each was the current one (empty with
    /// the spreading off; dynamic_objects.hpp).
    std::deque<ScanObjects> window_objects_;
    ScanObjects current_objects_;  ///< the current scan's, until it joins the window
    /// The motion test on the scans before each one (dynamic.motion; null when off).
    std::unique_ptr<PastMotion> past_motion_;
    /// Range images of the last dynamic.vote_frames scans, with their map-to-sensor transforms.
    std::deque<std::pair<Eigen::Isometry3f, RangeImage>> voters_;
    /// With end votes (keeps_scan_images()): each window scan's range image (not prepared) and
    /// map-to-sensor transform, so that the kept scans can vote on each other's points before
    /// the consolidation; empty images otherwise. In step with window_.
    std::deque<std::pair<Eigen::Isometry3f, RangeImage>> window_images_;
    /// add_old_viewpoints(): map-to-sensor transforms and range images of the old drive.
    std::vector<std::pair<Eigen::Isometry3f, RangeImage>> old_viewpoints_;
    std::pair<Eigen::Isometry3f, RangeImage> current_image_;  ///< the scan being added
    RangeImage spare_image_;  ///< the image of the scan that last left the window, for its buffers
    std::vector<IncrementalFrameStats> frames_;
    MappingStats stats_;
    std::uint64_t iteration_ = 0;
    bool origin_set_ = false;
    std::size_t start_rows_ = 0;            ///< rows of the map start_from() continued
    std::vector<float> start_features_;     ///< their saved values, start_rows_ x feature_dim
    std::size_t released_state_bytes_ = 0;  ///< state_bytes() when the state was released
    float consolidation_band_m_ = 0.0f;     ///< sampling.surface_band_m before incremental's
    ConsolidationStats consolidation_;
};

}  // namespace shine
