// Batch-mode mapping (paper Sec. III-B): all scans are loaded, the map is allocated around all
// their points, then features and decoder are optimised jointly on rays drawn from every scan.
//
// With the dynamic-point filter (config.dynamic, free_space_votes.hpp) each scan's points are
// voted on by the dynamic.vote_frames scans before and after it, and by the scans up to
// dynamic.far_vote_frames away as far voters, as the scans arrive (only that many range images
// are held); the points other scans see through are dropped before training,
// and the map is allocated around the kept points only, when training starts.
#pragma once

#include <cstdint>
#include <deque>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <vector>

#include "shine/io/preprocess.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/mapper_config.hpp"
#include "shine/mapper/pose_refinement.hpp"
#include "shine/mapper/stage_profile.hpp"
#include "shine/model/neural_sdf.hpp"
#include "shine/sampling/free_space_votes.hpp"
#include "shine/sampling/range_image.hpp"
#include "shine/sampling/ray_set.hpp"

namespace shine {

class BinaryReader;
class BinaryWriter;
class Trainer;

/// Wall-clock seconds per stage and sizes, for stats.json.
struct MappingStats {
    std::size_t frames = 0;
    std::size_t rays = 0;
    PreprocessStats preprocess;
    double load_seconds = 0.0;  ///< reading and preprocessing scans (dynamic_seconds included)
    /// Points the dynamic-point filter dropped (free_space_votes.hpp); rays counts them too.
    std::size_t dynamic_points_dropped = 0;
    /// Objects of single scans dropped whole because enough of their points were dynamic
    /// (dynamic_objects.hpp).
    std::size_t dynamic_objects = 0;
    /// Objects of single scans that move over the scans around them or lie where a moving one
    /// is predicted (moving_objects.hpp); their points are dynamic.
    std::size_t moving_objects = 0;
    double dynamic_seconds = 0.0;   ///< range images and free-space votes
    double allocate_seconds = 0.0;  ///< growing the octree
    double normals_seconds = 0.0;   ///< surface normals for the label correction
    double train_seconds = 0.0;
    double sample_seconds = 0.0;  ///< the part of train_seconds spent drawing samples
    std::size_t iterations = 0;
    double final_bce = 0.0;
    double final_eikonal = 0.0;
};

/// Batch mode's share of draws over every point at outdoor leaves of 0.2 m and coarser
/// (apply_batch_defaults()).
inline constexpr float kCoarseOutdoorEveryPointShare = 0.15f;

/// Batch mode's defaults outdoors, each unless its key is set (docs/heldout.md, docs/field.md):
/// - every point is kept, grouped by voxel (preprocess.voxel_points all): a drawn ray is, with
///   probability sampling.every_point_share, any of the points (dense near the sensor), otherwise
///   any point of a voxel drawn uniformly (spread over space as thinning's one point a voxel).
///   - At 0.2 m leaves (and coarser) 15 % of the draws go over the points
///     (kCoarseOutdoorEveryPointShare). Measured with pose refinement and deskew, every 3rd scan
///     held out, rays within 10 cm against one point a voxel: real drive 74.21 -> 76.31 %,
///     real walk 90.26 -> 90.54 %, the bundled street's F-score 95.53 -> 95.41 %. With 0 % the
///     street keeps 95.55 % but the drive gains less (75.08 %); with 30 % / 70 % the drive
///     reaches 76.34 / 76.94 % but the street falls to 95.16 / 94.41 %: a share over the points
///     trains where the rays are dense, which held-out rays reward and a street's F-score (by
///     area) does not. Every point costs the street at 5 cm / 0.3 deg pose noise more than the
///     share does: 94.57 -> 94.15 % (94.27 % with 0 %), its refined poses 3.9 -> 4.7 mm ATE.
///   - At leaves finer than 0.2 m 70 % (SamplingConfig's default): on the real walk at 0.1 m the
///     held-out rays within 10 cm rise from 88.41 to 88.96 % and the median error falls from
///     2.50 to 2.29 cm; with the 0.1 m schedule's 1000 steps the streets score 0.1-0.3 points
///     below thinning's.
/// - with the automatic schedule (training.iterations and batch_size not set), no Eikonal term
///   (training.eikonal_weight 0): the BCE labels already give the SDF its metric slope where the
///   samples are, and the term's second derivatives cost a sixth of a training step. A short
///   set schedule keeps it: after 20 steps a small street scored F 0.51 at 20 cm without it,
///   0.83 with it. Measured with pose refinement, every 3rd scan held out, rays within 10 cm
///   against 0.1: real drive 76.24 -> 76.47 %, real walk 90.56 -> 90.64 %, the bundled street's
///   F-score 95.39 -> 96.03 %, the street with 5 cm / 0.3 deg pose noise 94.13 -> 94.72 %; batch
///   runs 9-13 % shorter (docs/field.md). Incremental mode keeps it: there the drive lost 0.9
///   points.
/// - at leaves finer than 0.2 m, the surface is baked inside the allocated cells of level 1
///   (bake.mask_level 1). Where returns are sparse the finest cells do not touch and the mesh
///   has holes: on the real walk at 0.1 m the held-out rays that hit rise from 98.3 to 99.0 % and
///   those within 10 cm by 0.4 points; incremental mode, whose map is less smooth between its
///   cells, loses 1.2-2.8 F-score points on the streets with it, so it keeps 0.
void apply_batch_defaults(MapperConfig& config);

class BatchMapper {
  public:
    /// Finalizes `config` and applies apply_batch_defaults(); config() is the result, which
    /// the products of the map are made with (write_map_products).
    explicit BatchMapper(const MapperConfig& config);
    ~BatchMapper();

    /// Preprocesses a scan, moves it to the map frame and allocates the map around it (with the
    /// dynamic-point filter: votes on it and its neighbours instead; the map is allocated when
    /// training starts). The first scan fixes the map origin (its position rounded to whole
    /// kilometres). Returns the seconds of its preprocess and allocate stages.
    StageSeconds add_scan(const Scan& scan);

    /// Runs the config.batch_iterations() optimisation steps not yet done; `on_progress(done,
    /// bce)` is called now and then. With `stop`, polled after every step, training pauses when
    /// it returns true: train() then returns false and a later call (or one after save_state /
    /// load_state) continues where it stopped, to the same result. Returns true when every step
    /// has run.
    bool train(const std::function<void(std::size_t done, double bce)>& on_progress = {},
               const std::function<bool()>& stop = {});

    /// The configuration the mapper runs with (finalized, with the batch bake default).
    const MapperConfig& config() const { return config_; }
    /// Steps done so far.
    int iterations_done() const { return iterations_done_; }
    /// The steps this run trains: config.batch_schedule() for this map's corner count (known once
    /// the scans are added and finish_scans() ran; the automatic schedule follows it), or for
    /// the count set with set_schedule_corners().
    int planned_iterations() const;
    /// Sizes the automatic schedule by `corners` instead of this map's count (0: this map's).
    /// Batch mode's map at the refined poses takes the first phase's, so that both phases run
    /// the same schedule and a warm start resumes at the step the first phase stopped.
    void set_schedule_corners(std::size_t corners) { schedule_corners_ = corners; }
    /// The corner count the schedule is sized by.
    std::size_t schedule_corners() const;

    /// The training state (parameters, optimiser, step count, stats) for a checkpoint.
    /// load_state() expects the same scans to have been added again first (it checks the counts)
    /// and throws IoError via the reader where the state does not fit.
    void save_state(BinaryWriter& out) const;
    void load_state(BinaryReader& in);

    /// Each scan's pose T_world_sensor as trained: the given pose, or its refinement once a round
    /// of pose refinement ran (config.refine, pose_refinement.hpp).
    std::vector<Eigen::Isometry3d> poses_world() const;
    /// Pose refinement's first phase: trains this map up to the step of the last round of
    /// config.refine, running the rounds on the way, and returns the refined poses (world frame,
    /// one per scan; the given ones when config.refine.rounds is 0). train() never refines: it
    /// trains at the poses the scans have (map_sequence() makes the map at refined poses).
    /// Returns std::nullopt when `stop` returned true (polled after every step): the rounds
    /// left were not run.
    std::optional<std::vector<Eigen::Isometry3d>> refine_poses(
        const std::function<void(std::size_t done, double bce)>& on_progress = {},
        const std::function<bool()>& stop = {});
    /// Starts the training from `source` instead of from scratch: ends the loading
    /// (finish_scans()), copies the decoder and the features of every corner both maps have
    /// (FeatureOctree::copy_shared_features; the others keep their initial values) and counts
    /// the steps before `first_step` as done, so that train() runs the rest of the schedule on
    /// its cosine decay. For pose refinement's second phase (map_sequence): the same scans at
    /// the refined poses start from the first phase's map. Call before train(); throws
    /// ConfigError when training has begun or the maps differ in origin, octree or decoder.
    /// Returns the corners copied.
    std::size_t warm_start(const NeuralSdf& source, int first_step);
    /// config.refine at this map's leaf and range limits.
    PoseRefinementConfig refinement() const;
    /// The steps of refine_poses(): the last round's step (0 without refinement).
    int refinement_steps() const;
    /// The rounds of pose refinement run so far.
    const std::vector<PoseRefinementRound>& refinement_rounds() const { return rounds_; }
    /// How the poses the first phase trained at (the given ones before the first round, each
    /// round's before the next) differ from the refined ones in consecutive scans' relative
    /// poses: the largest median translation and rotation over those stretches
    /// (relative_pose_change(); zeros before the rounds ran).
    RelativePoseChange refinement_relative_change() const;

    const NeuralSdf& sdf() const { return *sdf_; }
    NeuralSdf& sdf() { return *sdf_; }
    const MappingStats& stats() const { return stats_; }
    const RaySet& rays() const { return rays_; }

    /// Ends the loading: with the dynamic-point filter, drops the dynamic points and allocates the
    /// map around the rest (once); before training, puts the map's feature rows in tree order
    /// (FeatureOctree::renumber_rows_in_tree_order; again only if the map grew). train() and
    /// load_state() call it; call it before planned_iterations() or the map's size are needed,
    /// as they depend on the map.
    void finish_scans();

  private:
    /// finish_scans()' first part: with the dynamic-point filter, drops the dynamic points and
    /// allocates the map around the rest (once).
    void drop_dynamic_points();
    /// The steps of train() up to `until`; `refining` (refine_poses()): with the rounds of pose
    /// refinement due on the way and at `until`.
    bool run_steps(int until, bool refining,
                   const std::function<void(std::size_t, double)>& on_progress,
                   const std::function<bool()>& stop);
    /// A scan that still votes on the scans after it.
    struct Voter {
        std::uint32_t scan = 0;
        Eigen::Isometry3f T_sensor_map;
        RangeImage image;
    };

    MapperConfig config_;
    std::unique_ptr<NeuralSdf> sdf_;
    RaySet rays_;
    MappingStats stats_;
    bool origin_set_ = false;
    /// Each scan's current pose in the map frame (moved by pose refinement).
    std::vector<Eigen::Isometry3d> poses_map_;
    std::vector<PoseRefinementRound> rounds_;
    std::vector<std::vector<Eigen::Isometry3d>> round_start_poses_;  ///< poses before each round
    std::deque<Voter> voters_;  ///< the last max(dynamic.vote_frames, far_vote_frames) scans
    /// Per voxel group of rays (per ray when ungrouped), until the dynamic points are dropped:
    /// a group is voted on at its first point, the one thinning keeps, and kept or dropped whole.
    std::vector<FreeSpaceVotes> votes_;
    /// The groups' first endpoints, contiguous, while votes are taken (grouped rays only).
    std::vector<Eigen::Vector3f> group_leads_;
    std::vector<std::filesystem::path> scan_sources_;  ///< per scan, for the budget's message
    bool dynamic_dropped_ = false;
    // Training state, kept between train() calls.
    std::unique_ptr<Trainer> trainer_;
    /// Corners when finish_scans() last put the rows in tree order (0: never).
    std::size_t renumbered_corners_ = 0;
    bool normals_done_ = false;
    std::size_t schedule_corners_ = 0;  ///< set_schedule_corners()
    int iterations_done_ = 0;
    double bce_average_ = 0.0;
};

}  // namespace shine
