// All settings of a mapping run in one struct with the paper's defaults (see DESIGN.md), and
// their YAML form. Parsing rejects unknown keys and out-of-range values, naming the key.
//
// Scale-free defaults. The length defaults below are the outdoor ones at 0.2 m leaves. A user who
// maps a room or an object sets only the leaf size (or only the scene): finalize() then moves
// every length the user did not set (set_keys) --
//   - with the leaf, in proportion to leaf / 0.2 m: preprocess.voxel_downsample_m,
//     sampling.normal_radius_m, training.sigma_m, incremental.surface_band_m (bake.voxel_size_m 0
//     is already half the leaf);
//   - with the surface band (the data's accuracy): dynamic.margin_m, twice sampling.surface_band_m;
//   - with the scene (map.scene, scene_preset.hpp; "auto" infers it from the leaf): the range
//     crop preprocess.min_range_m / max_range_m, the surface band sampling.surface_band_m (the
//     data's accuracy, not the resolution; at least half a leaf), and the leaf itself when only
//     the scene is given; outdoors, for leaves finer than 0.2 m, map.num_levels (one more level
//     per halving of the leaf, so the coarsest cell stays 0.8 m: 4 levels at 0.1 m).
// A 0.1 m outdoor map thus thins and labels at half the street's lengths but keeps its 0.1 m band
// and still sees 1.5 - 60 m; at 0.2 m outdoors nothing changes. Ratios, counts and the training
// schedule (batch_schedule(), which already follows the leaf) are not lengths and stay as they are.
#pragma once

#include <filesystem>
#include <set>
#include <string>
#include <vector>

#include "shine/bake/level_set_bake.hpp"
#include "shine/io/preprocess.hpp"
#include "shine/io/scene_preset.hpp"
#include "shine/map/feature_octree.hpp"
#include "shine/mapper/incremental_config.hpp"
#include "shine/mapper/odometry_config.hpp"
#include "shine/mapper/pose_refinement.hpp"
#include "shine/mapper/sequence_deskew.hpp"
#include "shine/mapper/trainer.hpp"
#include "shine/mesh/level_set_mesh.hpp"
#include "shine/model/decoder.hpp"
#include "shine/sampling/free_space_votes.hpp"
#include "shine/sampling/ray_sampler.hpp"
#include "shine/sampling/surface_normals.hpp"

namespace shine {

/// PreprocessConfig's defaults with the mapper's voxel size (MapperConfig::preprocess).
PreprocessConfig mapper_preprocess_defaults();

/// What batch mode trains with (MapperConfig::batch_schedule()).
struct BatchSchedule {
    int batch_size = 0;          ///< samples per step
    float learning_rate = 0.0f;  ///< the features' initial Adam learning rate
    int iterations = 0;          ///< steps
};

struct MapperConfig {
    /// The defaults below, with batch mode's samples per step and feature learning rate left
    /// automatic (0) for batch_schedule() to choose.
    MapperConfig();

    /// The scans' preprocessing, with one point kept per 0.2 m voxel (PreprocessConfig's own
    /// default, which the TSDF baseline keeps, is 0.05 m): a 0.05 m grid keeps most points near
    /// the sensor, so most training samples would land on the few metres around it. Measured on
    /// the street (docs/performance.md): higher F-scores in both modes at 0.2 m leaves, with a
    /// quarter of the rays to sample, find normals for and allocate. On held-out real scans a
    /// finer thinning scores slightly better at 0.2 m and clearly better at 0.1 m leaves, where
    /// 0.2 m thinning leaves most cells without a point (docs/heldout.md). Batch mode outdoors
    /// keeps every point instead, grouped by these voxels (apply_batch_defaults()).
    PreprocessConfig preprocess = mapper_preprocess_defaults();
    FeatureOctreeConfig octree;
    DecoderConfig decoder;
    SamplingConfig sampling;
    NormalConfig normals;  ///< endpoint normals for labels that are true distances
    /// Drops the points other scans see through (moving objects) before training; YAML section
    /// `dynamic`, `shine map --dynamic-filter off` turns it off (docs/movers.md).
    DynamicPointConfig dynamic;
    /// The optimiser. In batch mode trainer.batch_size 0 and trainer.feature_adam.learning_rate 0
    /// (the defaults) are automatic: batch_schedule() chooses them.
    TrainerConfig trainer;
    /// Batch-mode optimisation steps; -1 (the default) = auto, batch_schedule().
    int iterations = -1;
    /// lr decays to this fraction (cosine) by the end (batch: of the run; incremental: of each
    /// scan's steps)
    float final_learning_rate_ratio = 0.1f;
    IncrementalConfig incremental;  ///< `shine map --mode incremental`
    OdometryConfig odometry;        ///< poses estimated while mapping (incremental mode)
    DeskewConfig deskew;            ///< scans with per-point times (`shine map --deskew`)
    /// Batch mode: the scans' poses refined with the map between training steps
    /// (pose_refinement.hpp); YAML section `refine`, `shine map --no-refine` turns it off.
    PoseRefinementConfig refine;
    BakeConfig bake;
    MeshConfig mesh;
    /// Memory budget of the map (features + structure + decoder, MB = 10^6 bytes), checked after
    /// each scan's allocation (map_budget.hpp); 0 = unlimited. YAML: map.max_map_mb.
    double max_map_mb = 0.0;
    /// The map frame's origin in the world, [E, N, U] m; empty (the default): the first scan's
    /// position rounded to whole kilometres (map_frame.hpp). Maps that are merged (tiles) need
    /// the same origin. YAML: map.origin_world_m.
    std::vector<double> origin_world_m;
    /// Only points whose world position lies in this box are mapped, [xmin, ymin, zmin, xmax,
    /// ymax, zmax] m; empty (the default): no crop. A tile of a larger map uses its box grown
    /// by an overlap. YAML: preprocess.crop_world_m.
    std::vector<double> crop_world_m;
    int threads = 0;          ///< 0: all hardware threads
    std::uint64_t seed = 42;  ///< one seed for features, decoder and sampling
    /// The kind of scene: "outdoor", "indoor", "object" (scene_preset.hpp), or "auto" (the
    /// default): the one the leaf size suggests (scene_for_leaf). It decides the range crop and,
    /// when map.leaf_size_m is not set, the leaf size. YAML: map.scene.
    std::string scene = "auto";
    /// Keys ("section.key", as in YAML) the user set, in a file or with a flag: finalize() keeps
    /// their values. parse_config_yaml() adds every key it reads; the CLI calls mark_set().
    std::set<std::string> set_keys;

    /// Records that the user set `key` ("map.leaf_size_m").
    void mark_set(const std::string& key) { set_keys.insert(key); }
    /// Whether the user set `key`.
    bool is_set(const std::string& key) const { return set_keys.count(key) > 0; }
    /// Whether `field`, the value of `key`, is a default that another default may replace: the
    /// user did not set `key` and the field still holds `default_value`.
    template <class T>
    bool holds_default(const std::string& key, const T& field, const T& default_value) const {
        return !is_set(key) && field == default_value;
    }
    /// The scene `scene` names, or for "auto" the one the leaf size suggests. Throws ConfigError
    /// naming map.scene for an unknown name.
    ScenePreset resolved_scene() const;
    /// Outdoors at a leaf finer than the street's 0.2 m (below 0.15 m): where batch mode keeps
    /// every point and bakes in the level-1 cells (apply_batch_defaults()) and incremental mode's
    /// built-in decoder is the one pretrained at 0.1 m (load_incremental_decoder()).
    bool fine_outdoor_leaf() const;
    /// `refine` at this configuration's leaf and range limits (PoseRefinementConfig::at_leaf):
    /// what both mappers register with.
    PoseRefinementConfig scaled_refinement() const;
    /// Whether incremental mode's consolidation refines the kept scans' poses: refine.rounds > 0
    /// and refine.in_consolidation (given and estimated poses alike).
    bool refines_in_consolidation() const;

    /// Whether batch mode trains on the automatic schedule: `iterations` and trainer.batch_size
    /// both automatic (batch_schedule()).
    bool automatic_batch_schedule() const { return iterations < 0 && trainer.batch_size == 0; }

    /// Batch mode's samples per step, learning rate and steps. With `iterations` and
    /// trainer.batch_size both automatic (the defaults), the automatic schedule: 32768 samples
    /// per step at learning rate 0.03 (unless set), 250 steps at 0.2 m leaves, 250 *
    /// (0.2 m / leaf)^2 for finer leaves (a surface map has ~4x the features per halving of the
    /// leaf, and each row needs as many samples; 1000 at 0.1 m, where the corner cap below gives
    /// the street 947) and 250 * leaf / 0.2 m for coarser ones up to 500 at 0.4 m and beyond (a
    /// coarse map's few rows are touched in nearly every step, and what counts there is the
    /// number of Adam steps), at most 6250. On the street and two other seeds it scores as well
    /// as or better than the paper's 4096-sample steps with 17-19 % fewer samples at 0.2 m
    /// (docs/performance.md); at 0.1 m the steps of (0.2 m / leaf)^2 instead of the earlier
    /// ^1.5 (707) add 0.0-0.2 points on the streets (docs/heldout.md). Setting either keeps the
    /// paper's steps: 4096 samples (unless set), learning rate 0.01 (unless set) and, for automatic
    /// iterations, 2400 steps at 0.2 m and coarser, 2400 * (0.2 m / leaf)^1.5 for finer leaves, at
    /// most 50,000.
    ///
    /// With the map's corner count (`num_corners`, all levels; 0 = unknown; batch mode always
    /// knows it) the automatic schedule follows the scene instead of the leaf: 250 steps per
    /// kScheduleCornersPerUnit corners (the bundled street's at 0.2 m), never fewer than 250, at
    /// most 6250: each corner gets as many samples whatever the scene's size. An object at 3 mm
    /// (186,624 corners) trains 250 steps; streets at 0.1 m (1.59-1.66 M corners) 907-947; at 0.2 m
    /// the bundled street 251, the real drive 263 and the real walk 271 (the count of batch
    /// mode's first phase, BatchMapper::set_schedule_corners). Before, at 0.2 m every scene trained
    /// 250 steps and larger ones were under-trained (docs/field.md, Log): a 100-scan street (1.5
    /// streets of corners) F 93.77 % against 95.24 % at 381 steps, a 0.4 km route (3.9
    /// streets) 91.58 % against 96.50 % at 975.
    BatchSchedule batch_schedule(std::size_t num_corners = 0) const;
    /// Corners of the bundled street's 0.2 m map: one unit of the scene-following cap.
    static constexpr double kScheduleCornersPerUnit = 438267.0;
    /// batch_schedule(num_corners).iterations.
    int batch_iterations(std::size_t num_corners = 0) const {
        return batch_schedule(num_corners).iterations;
    }
    /// `trainer` with batch_schedule()'s samples per step and learning rate.
    TrainerConfig batch_trainer() const;

    /// Applies the scale-free defaults (file comment) to the lengths the user did not set, copies
    /// feature_dim/seed into the sub-configs that repeat them, and checks ranges. Idempotent: a
    /// length is moved only while it still holds its outdoor default.
    void finalize();
};

/// Reads `path` (YAML) over the defaults in `config`. Throws ConfigError naming the file and key.
void load_config_yaml(const std::filesystem::path& path, MapperConfig& config);

/// The configuration as YAML (stored in map.vdb and accepted by load_config_yaml).
std::string config_to_yaml(const MapperConfig& config);

/// Parses YAML text (as produced by config_to_yaml) over `config`; `source` names it in errors.
void parse_config_yaml(const std::string& text, const std::string& source, MapperConfig& config);

}  // namespace shine
