#include "shine/mapper/mapper_config.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <sstream>
#include <type_traits>

#include "shine/core/error.hpp"

namespace shine {
namespace {

// One table of keys: each entry reads a YAML scalar into the field, checks its range and writes
// it back. Keeping read and write together keeps the YAML form and the struct in step.
struct Field {
    std::function<void(const YAML::Node&, const std::string& key)> read;
    std::function<void(YAML::Emitter&)> write;
};

template <typename T>
T as(const YAML::Node& node, const std::string& key) {
    try {
        return node.as<T>();
    } catch (const YAML::Exception&) {
        throw ConfigError("key '" + key + "': cannot read '" + YAML::Dump(node) + "' as a " +
                          (std::is_same_v<T, bool> ? "boolean" : "number"));
    }
}

template <typename T>
Field number(T& field, double lo, double hi) {
    return {[&field, lo, hi](const YAML::Node& node, const std::string& key) {
                const T value = as<T>(node, key);
                if (!(static_cast<double>(value) >= lo && static_cast<double>(value) <= hi)) {
                    std::ostringstream msg;
                    msg << "key '" << key << "': " << value << " is out of range [" << lo << ", "
                        << hi << "]";
                    throw ConfigError(msg.str());
                }
                field = value;
            },
            [&field](YAML::Emitter& out) { out << field; }};
}

Field boolean(bool& field) {
    return {
        [&field](const YAML::Node& node, const std::string& key) { field = as<bool>(node, key); },
        [&field](YAML::Emitter& out) { out << field; }};
}

Field int_list(std::vector<int>& field, int lo, int hi) {
    return {[&field, lo, hi](const YAML::Node& node, const std::string& key) {
                if (!node.IsSequence()) throw ConfigError("key '" + key + "' must be a list");
                std::vector<int> values;
                for (const auto& item : node) {
                    const int v = as<int>(item, key);
                    if (v < lo || v > hi) {
                        throw ConfigError("key '" + key + "': " + std::to_string(v) +
                                          " is out of range");
                    }
                    values.push_back(v);
                }
                field = values;
            },
            [&field](YAML::Emitter& out) {
                out << YAML::Flow << YAML::BeginSeq;
                for (int v : field) out << v;
                out << YAML::EndSeq;
            }};
}

/// A list of exactly `count` finite numbers, or the empty list [] (= unset).
Field double_list(std::vector<double>& field, std::size_t count) {
    return {[&field, count](const YAML::Node& node, const std::string& key) {
                if (!node.IsSequence()) throw ConfigError("key '" + key + "' must be a list");
                std::vector<double> values;
                for (const auto& item : node) {
                    const double v = as<double>(item, key);
                    if (!std::isfinite(v)) {
                        throw ConfigError("key '" + key + "': values must be finite numbers");
                    }
                    values.push_back(v);
                }
                if (!values.empty() && values.size() != count) {
                    throw ConfigError("key '" + key + "' needs " + std::to_string(count) +
                                      " numbers (or [] for none), got " +
                                      std::to_string(values.size()));
                }
                field = values;
            },
            [&field](YAML::Emitter& out) {
                out << YAML::Flow << YAML::BeginSeq;
                for (double v : field) out << v;
                out << YAML::EndSeq;
            }};
}

/// The text of a scalar value; a list or mapping is a ConfigError naming the key (yaml-cpp would
/// throw its own exception, which is not a shine::Error).
std::string scalar_text(const YAML::Node& node, const std::string& key) {
    if (!node.IsScalar()) throw ConfigError("key '" + key + "' must be a single value");
    return node.Scalar();
}

/// A setting with two named values.
template <class Enum>
Field either(Enum& field, const char* first_name, Enum first, const char* second_name,
             Enum second) {
    const std::string a = first_name, b = second_name;
    return {[&field, a, b, first, second](const YAML::Node& node, const std::string& key) {
                const std::string v = scalar_text(node, key);
                if (v == a)
                    field = first;
                else if (v == b)
                    field = second;
                else
                    throw ConfigError("key '" + key + "': expected '" + a + "' or '" + b +
                                      "', got '" + v + "'");
            },
            [&field, a, b, first](YAML::Emitter& out) { out << (field == first ? a : b); }};
}

Field text(std::string& field) {
    return {[&field](const YAML::Node& node, const std::string& key) {
                if (!node.IsScalar()) throw ConfigError("key '" + key + "' must be a string");
                field = node.as<std::string>();
            },
            [&field](YAML::Emitter& out) { out << field; }};
}

/// map.scene: "auto" or a preset's name.
Field scene_name(std::string& field) {
    return {[&field](const YAML::Node& node, const std::string& key) {
                const std::string v = scalar_text(node, key);
                if (v != "auto" && v != "outdoor" && v != "indoor" && v != "object") {
                    throw ConfigError("key '" + key +
                                      "': expected 'auto', 'outdoor', 'indoor' or 'object', got '" +
                                      v + "'");
                }
                field = v;
            },
            [&field](YAML::Emitter& out) { out << field; }};
}

Field precision(FeaturePrecision& field) {
    return {[&field](const YAML::Node& node, const std::string& key) {
                field = parse_feature_precision(scalar_text(node, key), key);
            },
            [&field](YAML::Emitter& out) { out << to_string(field); }};
}

Field interpolation(Interpolation& field) {
    return {[&field](const YAML::Node& node, const std::string& key) {
                field = parse_interpolation(scalar_text(node, key), key);
            },
            [&field](YAML::Emitter& out) { out << to_string(field); }};
}

/// deskew.mode: auto, on or off.
Field deskew_mode(DeskewMode& field) {
    return {[&field](const YAML::Node& node, const std::string& key) {
                const std::string v = scalar_text(node, key);
                if (v == "auto") {
                    field = DeskewMode::kAuto;
                } else if (v == "on") {
                    field = DeskewMode::kOn;
                } else if (v == "off") {
                    field = DeskewMode::kOff;
                } else {
                    throw ConfigError("key '" + key + "': expected 'auto', 'on' or 'off', got '" +
                                      v + "'");
                }
            },
            [&field](YAML::Emitter& out) { out << to_string(field); }};
}

constexpr double kInf = 1e300;

using Section = std::vector<std::pair<std::string, Field>>;

std::vector<std::pair<std::string, Section>> schema(MapperConfig& c) {
    return {
        {"preprocess",
         {{"min_range_m", number(c.preprocess.min_range_m, 0.0, kInf)},
          {"max_range_m", number(c.preprocess.max_range_m, 0.0, kInf)},
          {"voxel_downsample_m", number(c.preprocess.voxel_downsample_m, 0.0, 10.0)},
          {"voxel_points", either(c.preprocess.voxel_points, "nearest", VoxelPoints::kNearest,
                                  "all", VoxelPoints::kAll)},
          {"invalid_points", either(c.preprocess.invalid_points, "error",
                                    InvalidPointPolicy::kError, "drop", InvalidPointPolicy::kDrop)},
          {"crop_world_m", double_list(c.crop_world_m, 6)}}},
        {"map",
         {{"leaf_size_m", number(c.octree.leaf_size_m, 1e-3, 100.0)},
          {"num_levels", number(c.octree.num_levels, 1, 8)},
          {"feature_dim", number(c.octree.feature_dim, 1, 64)},
          {"init_std", number(c.octree.init_std, 0.0, 10.0)},
          {"allocation_margin_ratio", number(c.octree.allocation_margin_ratio, 0.0, 4.0)},
          {"feature_precision", precision(c.octree.feature_precision)},
          {"interpolation", interpolation(c.octree.interpolation)},
          {"max_map_mb", number(c.max_map_mb, 0.0, 1e9)},
          {"origin_world_m", double_list(c.origin_world_m, 3)},
          {"scene", scene_name(c.scene)}}},
        {"decoder", {{"hidden_dims", int_list(c.decoder.hidden_dims, 1, 1024)}}},
        {"sampling",
         {{"surface_samples", number(c.sampling.surface_samples, 0, 32)},
          {"free_samples", number(c.sampling.free_samples, 0, 32)},
          {"surface_band_m", number(c.sampling.surface_band_m, 1e-4, 10.0)},
          {"free_space_start_ratio", number(c.sampling.free_space_start_ratio, 0.0, 1.0)},
          {"use_normals", boolean(c.normals.enabled)},
          {"surface_samples_along_normal", boolean(c.sampling.surface_samples_along_normal)},
          {"min_incidence_cosine", number(c.sampling.min_incidence_cosine, 1e-3, 1.0)},
          {"every_point_share", number(c.sampling.every_point_share, 0.0, 1.0)},
          {"normal_neighbors", number(c.normals.neighbors, 5, 64)},
          {"normal_radius_m", number(c.normals.max_radius_m, 1e-4, 100.0)}}},
        {"training",
         {{"iterations", number(c.iterations, -1, 10000000)},
          {"batch_size", number(c.trainer.batch_size, 0, 1 << 22)},
          {"sigma_m", number(c.trainer.sigma_m, 1e-5, 10.0)},
          {"eikonal_weight", number(c.trainer.eikonal_weight, 0.0, 100.0)},
          {"learning_rate", number(c.trainer.feature_adam.learning_rate, 0.0, 10.0)},
          {"decoder_learning_rate", number(c.trainer.decoder_adam.learning_rate, 1e-7, 10.0)},
          {"final_learning_rate_ratio", number(c.final_learning_rate_ratio, 0.0, 1.0)},
          {"train_decoder", boolean(c.trainer.train_decoder)}}},
        {"incremental",
         {{"iterations_per_frame", number(c.incremental.iterations_per_frame, 1, 1000000)},
          {"regularization_weight",
           number(c.incremental.importance.regularization_weight, 0.0, 1e12)},
          {"importance_cap", number(c.incremental.importance.importance_cap, 1e-12, 1e30)},
          {"decoder_weights", text(c.incremental.decoder_weights)},
          {"mesh_every", number(c.incremental.mesh_every, 0, 1000000)},
          {"learning_rate", number(c.incremental.learning_rate, 1e-7, 10.0)},
          {"batch_size", number(c.incremental.batch_size, 1, 1 << 22)},
          {"surface_band_m", number(c.incremental.surface_band_m, 1e-4, 10.0)},
          {"normal_window_frames", number(c.incremental.normal_window_frames, 1, 100)},
          {"normal_neighbors", number(c.incremental.normal_neighbors, 5, 64)},
          {"replay_frames", number(c.incremental.replay_frames, 1, 100000)},
          {"replay_current_share", number(c.incremental.replay_current_share, 0.0, 1.0)},
          {"importance_ray_stride", number(c.incremental.importance_ray_stride, 1, 1000)},
          {"active_frames", number(c.incremental.active_frames, 0, 100000000)},
          {"consolidation_steps", number(c.incremental.consolidation_steps, 0, 100000000)},
          {"consolidation_learning_rate",
           number(c.incremental.consolidation_learning_rate, 1e-7, 10.0)},
          {"consolidation_free_samples", number(c.incremental.consolidation_free_samples, 0, 32)},
          {"old_rows_importance", number(c.incremental.old_rows_importance, 0.0, 1e30)}}},
        {"keyframes",
         {{"enabled", boolean(c.incremental.keyframes.enabled)},
          {"min_translation_m", number(c.incremental.keyframes.min_translation_m, 1e-6, 1e6)},
          {"min_rotation_deg", number(c.incremental.keyframes.min_rotation_deg, 1e-6, 360.0)},
          {"max_interval_scans", number(c.incremental.keyframes.max_interval_scans, 1, 1000000)},
          {"keyframe_takes_deferred_steps",
           boolean(c.incremental.keyframes.keyframe_takes_deferred_steps)},
          {"min_coverage", number(c.incremental.keyframes.min_coverage, 0.0, 1.0)},
          {"forced_coverage", number(c.incremental.keyframes.forced_coverage, 0.0, 1.0)},
          {"max_ms_per_scan", number(c.incremental.keyframes.max_ms_per_scan, 0.0, 1e9)},
          {"max_saved_scans", number(c.incremental.keyframes.max_saved_scans, 1.0, 1e6)},
          {"max_deferred_scans",
           number(c.incremental.keyframes.max_deferred_scans, 0, 100000000)}}},
        {"odometry",
         {{"estimate_poses", boolean(c.odometry.estimate_poses)},
          {"voxel_size_m", number(c.odometry.voxel_size_m, 0.0, 100.0)},
          {"min_range_m", number(c.odometry.min_range_m, 0.0, kInf)},
          {"max_range_m", number(c.odometry.max_range_m, 0.0, kInf)},
          {"max_iterations", number(c.odometry.max_iterations, 1, 10000)},
          {"icp_warmup_scans", number(c.odometry.icp_warmup_scans, 0, 100000000)},
          {"icp_before_sdf", boolean(c.odometry.icp_before_sdf)},
          {"icp_reference_scans", number(c.odometry.icp_reference_scans, 1, 1000)},
          {"icp_max_correspondence_m", number(c.odometry.icp_max_correspondence_m, 1e-4, 100.0)},
          {"icp_kernel_scale_m", number(c.odometry.icp_kernel_scale_m, 1e-5, 100.0)},
          {"icp_yaw_hypotheses", number(c.odometry.icp_yaw_hypotheses, 1, 360)},
          {"icp_min_inlier_ratio", number(c.odometry.icp_min_inlier_ratio, 0.0, 1.0)},
          {"icp_coarse_correspondence_m",
           number(c.odometry.icp_coarse_correspondence_m, 0.0, 1000.0)},
          {"sdf_kernel_scale_m", number(c.odometry.sdf_kernel_scale_m, 1e-5, 100.0)},
          {"sdf_coarse_kernel_scale_m", number(c.odometry.sdf_coarse_kernel_scale_m, 0.0, 100.0)},
          {"sdf_min_incidence_cosine", number(c.odometry.sdf_min_incidence_cosine, 0.0, 1.0)},
          {"max_condition_number", number(c.odometry.max_condition_number, 1.0, 1e30)},
          {"min_scan_points", number(c.odometry.min_scan_points, 0, 100000000)},
          {"estimate_sweep", boolean(c.odometry.estimate_sweep)},
          {"sweep_prior_translation_m", number(c.odometry.sweep_prior_translation_m, 1e-6, 100.0)},
          {"sweep_prior_rotation_deg", number(c.odometry.sweep_prior_rotation_deg, 1e-6, 180.0)},
          {"sweep_prior_centre",
           either(c.odometry.sweep_prior_from_poses, "poses", true, "prediction", false)}}},
        {"refine",
         {{"rounds", number(c.refine.rounds, 0, 100)},
          {"first_fraction", number(c.refine.first_fraction, 0.0, 1.0)},
          {"last_fraction", number(c.refine.last_fraction, 0.0, 1.0)},
          {"voxel_size_m", number(c.refine.voxel_size_m, 1e-4, 100.0)},
          {"coarse_kernel_scale_m", number(c.refine.coarse_kernel_scale_m, 1e-5, 10.0)},
          {"kernel_scale_m", number(c.refine.kernel_scale_m, 1e-5, 10.0)},
          {"max_iterations", number(c.refine.max_iterations, 1, 1000)},
          {"max_points", number(c.refine.max_points, 0, 100000000)},
          {"gauge_lever_m", number(c.refine.gauge_lever_m, 1e-3, 1e4)},
          {"min_unfinished_cost_cut", number(c.refine.min_unfinished_cost_cut, 0.0, 1.0)},
          {"max_correction_m", number(c.refine.max_correction_m, 0.0, 1e4)},
          {"max_correction_deg", number(c.refine.max_correction_deg, 0.0, 180.0)},
          {"warm_start", boolean(c.refine.warm_start)},
          {"warm_start_max_relative_m", number(c.refine.warm_start_max_relative_m, 0.0, 100.0)},
          {"warm_start_max_relative_deg", number(c.refine.warm_start_max_relative_deg, 0.0, 180.0)},
          {"in_consolidation", boolean(c.refine.in_consolidation)}}},
        {"deskew",
         {{"mode", deskew_mode(c.deskew.mode)},
          {"scan_period_s", number(c.deskew.scan_period_s, 1e-4, 1e4)},
          {"azimuth_times", deskew_mode(c.deskew.azimuth_times)},
          {"sweep_direction",
           either(c.deskew.sweep.direction, "clockwise", SweepDirection::kClockwise,
                  "counterclockwise", SweepDirection::kCounterClockwise)},
          {"sweep_start_deg", number(c.deskew.sweep.start_azimuth_deg, -360.0, 360.0)},
          {"pose_azimuth_deg", number(c.deskew.sweep.pose_azimuth_deg, -360.0, 360.0)}}},
        {"dynamic",
         {{"enabled", boolean(c.dynamic.enabled)},
          {"vote_frames", number(c.dynamic.vote_frames, 1, 100000)},
          {"window_bins", number(c.dynamic.window_bins, 0, 16)},
          {"margin_m", number(c.dynamic.margin_m, 1e-6, 100.0)},
          {"beam_margin", number(c.dynamic.beam_margin, 0.0, 100.0)},
          {"min_free_votes", number(c.dynamic.min_free_votes, 1, 65535)},
          {"min_free_share", number(c.dynamic.min_free_share, 1e-6, 1.0)},
          {"far_vote_frames", number(c.dynamic.far_vote_frames, 0, 100000)},
          {"far_max_near_hits", number(c.dynamic.far_max_near_hits, 0, 65535)},
          {"far_min_free_share", number(c.dynamic.far_min_free_share, 1e-6, 1.0)},
          {"object_min_dynamic_share", number(c.dynamic.objects.min_dynamic_share, 0.0, 1.0)},
          {"object_min_points", number(c.dynamic.objects.min_points, 1, 100000000)},
          {"object_min_dynamic_points", number(c.dynamic.objects.min_dynamic_points, 1, 100000000)},
          {"object_voxel_m", number(c.dynamic.objects.voxel_m, 1e-4, 100.0)},
          {"object_ground_cell_m", number(c.dynamic.objects.ground_cell_m, 1e-4, 100.0)},
          {"object_min_height_m", number(c.dynamic.objects.min_height_m, 0.0, 100.0)},
          {"object_max_extent_m", number(c.dynamic.objects.max_extent_m, 1e-4, 1000.0)},
          {"object_max_height_m", number(c.dynamic.objects.max_height_m, 1e-4, 1000.0)},
          {"motion", boolean(c.dynamic.motion.enabled)},
          {"motion_while_mapping", boolean(c.dynamic.motion.while_mapping)},
          {"motion_voxel_height_m", number(c.dynamic.motion.voxel_height_m, 0.0, 100.0)},
          {"motion_match_m", number(c.dynamic.motion.match_m, 1e-4, 100.0)},
          {"motion_max_step_m", number(c.dynamic.motion.max_step_m, 1e-4, 1000.0)},
          {"motion_search_m", number(c.dynamic.motion.search_m, 1e-3, 100.0)},
          {"motion_min_step_m", number(c.dynamic.motion.min_step_m, 0.0, 1000.0)},
          {"motion_min_points", number(c.dynamic.motion.min_points, 1, 100000000)},
          {"motion_min_match_share", number(c.dynamic.motion.min_match_share, 0.0, 1.0)},
          {"motion_min_gain", number(c.dynamic.motion.min_gain, 0.0, 1.0)},
          {"motion_window_scans", number(c.dynamic.motion.window_scans, 1, 1000)},
          {"motion_min_window_scans", number(c.dynamic.motion.min_window_scans, 1, 1000)},
          {"motion_min_scan_share", number(c.dynamic.motion.min_scan_share, 0.0, 1.0)},
          {"motion_max_still_share", number(c.dynamic.motion.max_still_share, 0.0, 1.0)},
          {"motion_link_share", number(c.dynamic.motion.link_share, 0.0, 1.0)},
          {"motion_max_gap_scans", number(c.dynamic.motion.max_gap_scans, 1, 1000)}}},
        {"bake",
         {{"voxel_size_m", number(c.bake.voxel_size_m, 0.0, 100.0)},
          {"half_width_voxels", number(c.bake.half_width_voxels, 1.0, 100.0)},
          {"mask_level", number(c.bake.mask_level, 0, 7)}}},
        {"mesh",
         {{"adaptivity", number(c.mesh.adaptivity, 0.0, 1.0)},
          {"min_component_triangles", number(c.mesh.min_component_triangles, 0, 1e12)}}},
        {"run", {{"threads", number(c.threads, 0, 1024)}, {"seed", number(c.seed, 0, 1.8e19)}}},
    };
}

}  // namespace

PreprocessConfig mapper_preprocess_defaults() {
    PreprocessConfig config;
    config.voxel_downsample_m = 0.2;
    return config;
}

MapperConfig::MapperConfig() {
    trainer.batch_size = 0;
    trainer.feature_adam.learning_rate = 0.0f;
    // Measured on held-out real scans and on the simulated streets (docs/heldout.md): linear
    // weights and a 0.1 m surface band.
    octree.interpolation = Interpolation::kLinear;
    sampling.surface_band_m = 0.1f;
    // Half-precision features halve the map at no measured cost: F-score within +-0.03 points on
    // the three streets at 0.2 m (batch and incremental), 89.11 against 89.12 % on held-out real
    // scans (docs/benchmark.md, docs/heldout.md). Training keeps a float32 master copy.
    octree.feature_precision = FeaturePrecision::kFloat16;
}

bool MapperConfig::fine_outdoor_leaf() const {
    return resolved_scene() == ScenePreset::kOutdoor &&
           octree.leaf_size_m < 0.75 * MapperConfig{}.octree.leaf_size_m;
}

PoseRefinementConfig MapperConfig::scaled_refinement() const {
    return refine.at_leaf(octree.leaf_size_m, preprocess.min_range_m, preprocess.max_range_m);
}

bool MapperConfig::refines_in_consolidation() const {
    return refine.rounds > 0 && refine.in_consolidation;
}

ScenePreset MapperConfig::resolved_scene() const {
    if (scene == "auto") return scene_for_leaf(octree.leaf_size_m);
    if (scene == "outdoor" || scene == "indoor" || scene == "object") {
        return parse_scene_preset(scene, "map.scene");
    }
    throw ConfigError("map.scene: expected 'auto', 'outdoor', 'indoor' or 'object', got '" + scene +
                      "'");
}

namespace {

/// The scale-free defaults (mapper_config.hpp): each length the user did not set and that still
/// holds its outdoor default moves with the scene (ranges, leaf) or the leaf (the rest).
void apply_scale_free_defaults(MapperConfig& c) {
    const MapperConfig outdoor;
    const SceneDefaults scene = scene_defaults(c.resolved_scene());
    if (c.scene != "auto" &&
        c.holds_default("map.leaf_size_m", c.octree.leaf_size_m, outdoor.octree.leaf_size_m)) {
        c.octree.leaf_size_m = scene.leaf_size_m;
    }
    const auto from_scene = [&c](double& field, double outdoor_value, double scene_value,
                                 const char* key) {
        if (c.holds_default(key, field, outdoor_value)) field = scene_value;
    };
    from_scene(c.preprocess.min_range_m, outdoor.preprocess.min_range_m, scene.min_range_m,
               "preprocess.min_range_m");
    from_scene(c.preprocess.max_range_m, outdoor.preprocess.max_range_m, scene.max_range_m,
               "preprocess.max_range_m");
    if (c.holds_default("sampling.surface_band_m", c.sampling.surface_band_m,
                        outdoor.sampling.surface_band_m)) {
        // At least half a leaf, so that coarse maps (bench's 0.5 and 1 m leaves) keep samples on
        // both sides of every cell's surface.
        c.sampling.surface_band_m =
            static_cast<float>(std::max(scene.surface_band_m, 0.5 * c.octree.leaf_size_m));
    }
    // A hit is a return within the data's accuracy of the point: twice the surface band (0.2 m
    // outdoors, 9 mm on the object scene).
    if (c.holds_default("dynamic.margin_m", c.dynamic.margin_m, outdoor.dynamic.margin_m)) {
        c.dynamic.margin_m = 2.0f * c.sampling.surface_band_m;
    }
    // Moving objects are cars and people: on the object scene the whole scan is one compact
    // object, so its points keep their own votes (dynamic_objects.hpp).
    if (c.resolved_scene() == ScenePreset::kObject &&
        !c.is_set("dynamic.object_min_dynamic_share")) {
        c.dynamic.objects.min_dynamic_share = 0.0f;
    }
    // Likewise the motion test: its steps are those of cars and people between scans.
    if (c.resolved_scene() == ScenePreset::kObject && !c.is_set("dynamic.motion")) {
        c.dynamic.motion.enabled = false;
    }
    // Pose refinement (pose_refinement.hpp) is measured to win on streets and the real walk and
    // drive; on the object scene, whose simulated poses are exact, its rounds moved them by up to
    // 2.5 mm and cost 21.9 points of F-score at 1 mm (docs/object_scale.md).
    if (c.resolved_scene() == ScenePreset::kObject && !c.is_set("refine.rounds")) {
        c.refine.rounds = 0;
    }
    // Outdoors a leaf finer than 0.2 m keeps the coarse levels: one more level per halving of
    // the leaf, so the coarsest cell stays 0.8 m (4 levels at 0.1 m). Measured on real scans
    // and the streets at 0.1 m, in both modes (docs/heldout.md); not measured indoors or on
    // objects, whose leaves follow their own size alone.
    if (c.resolved_scene() == ScenePreset::kOutdoor &&
        c.holds_default("map.num_levels", c.octree.num_levels, outdoor.octree.num_levels) &&
        c.octree.leaf_size_m < outdoor.octree.leaf_size_m) {
        const auto finer_levels = static_cast<int>(
            std::lround(std::log2(outdoor.octree.leaf_size_m / c.octree.leaf_size_m)));
        c.octree.num_levels = std::min(c.octree.num_levels + finer_levels, 8);
    }
    // Exactly 1 at the outdoor leaf, so the street's lengths keep every bit.
    const double scale = c.octree.leaf_size_m / outdoor.octree.leaf_size_m;
    const auto follow_leaf = [&c, scale](auto& field, auto outdoor_value, const char* key) {
        using T = std::decay_t<decltype(field)>;
        if (c.holds_default(key, field, static_cast<T>(outdoor_value))) {
            field = static_cast<T>(static_cast<double>(outdoor_value) * scale);
        }
    };
    follow_leaf(c.preprocess.voxel_downsample_m, outdoor.preprocess.voxel_downsample_m,
                "preprocess.voxel_downsample_m");
    follow_leaf(c.normals.max_radius_m, outdoor.normals.max_radius_m, "sampling.normal_radius_m");
    follow_leaf(c.trainer.sigma_m, outdoor.trainer.sigma_m, "training.sigma_m");
    follow_leaf(c.incremental.surface_band_m, outdoor.incremental.surface_band_m,
                "incremental.surface_band_m");
    // Pose estimation: its range crop is the scene's, except outdoors, where the registration
    // keeps its own, shorter far end (odometry_config.hpp); its lengths follow the leaf.
    from_scene(c.odometry.min_range_m, outdoor.odometry.min_range_m, scene.min_range_m,
               "odometry.min_range_m");
    if (c.resolved_scene() != ScenePreset::kOutdoor) {
        from_scene(c.odometry.max_range_m, outdoor.odometry.max_range_m, scene.max_range_m,
                   "odometry.max_range_m");
    }
    follow_leaf(c.odometry.voxel_size_m, outdoor.odometry.voxel_size_m, "odometry.voxel_size_m");
    follow_leaf(c.odometry.icp_max_correspondence_m, outdoor.odometry.icp_max_correspondence_m,
                "odometry.icp_max_correspondence_m");
    follow_leaf(c.odometry.icp_coarse_correspondence_m,
                outdoor.odometry.icp_coarse_correspondence_m,
                "odometry.icp_coarse_correspondence_m");
    follow_leaf(c.odometry.icp_kernel_scale_m, outdoor.odometry.icp_kernel_scale_m,
                "odometry.icp_kernel_scale_m");
    follow_leaf(c.odometry.sdf_kernel_scale_m, outdoor.odometry.sdf_kernel_scale_m,
                "odometry.sdf_kernel_scale_m");
    follow_leaf(c.odometry.sdf_coarse_kernel_scale_m, outdoor.odometry.sdf_coarse_kernel_scale_m,
                "odometry.sdf_coarse_kernel_scale_m");
}

}  // namespace

BatchSchedule MapperConfig::batch_schedule(std::size_t num_corners) const {
    // The automatic schedule, measured on the street (docs/performance.md); otherwise the
    // paper's, which are TrainerConfig's own defaults (4096 samples, lr 0.01).
    constexpr int kAutoBatchSize = 32768;
    constexpr float kAutoLearningRate = 0.03f;
    const TrainerConfig paper;
    const bool automatic = automatic_batch_schedule();
    const double leaf_m = octree.leaf_size_m;
    BatchSchedule schedule;
    schedule.batch_size = trainer.batch_size > 0 ? trainer.batch_size
                          : automatic            ? kAutoBatchSize
                                                 : paper.batch_size;
    schedule.learning_rate = trainer.feature_adam.learning_rate > 0.0f
                                 ? trainer.feature_adam.learning_rate
                             : automatic ? kAutoLearningRate
                                         : paper.feature_adam.learning_rate;
    if (iterations >= 0) {
        schedule.iterations = iterations;
    } else if (automatic) {
        double steps = 0.0;
        if (num_corners > 0) {
            // 250 steps per street of corners, at every leaf and scene size.
            const double units = static_cast<double>(num_corners) / kScheduleCornersPerUnit;
            steps = 250.0 * std::max(units, 1.0);
        } else {
            // Without the map's corners: the steps a street-sized scene takes at this leaf.
            const double finer = std::pow(0.2 / leaf_m, 2.0);
            const double coarser = std::min(leaf_m / 0.2, 2.0);
            steps = 250.0 * std::max(finer, coarser);
        }
        schedule.iterations = static_cast<int>(std::lround(std::min(steps, 6250.0)));
    } else {
        const double scaled = 2400.0 * std::pow(0.2 / leaf_m, 1.5);
        schedule.iterations = static_cast<int>(std::lround(std::clamp(scaled, 2400.0, 50000.0)));
    }
    return schedule;
}

TrainerConfig MapperConfig::batch_trainer() const {
    const BatchSchedule schedule = batch_schedule();
    TrainerConfig config = trainer;
    config.batch_size = schedule.batch_size;
    config.feature_adam.learning_rate = schedule.learning_rate;
    return config;
}

void MapperConfig::finalize() {
    apply_scale_free_defaults(*this);
    decoder.input_dim = octree.feature_dim;
    octree.seed = seed;
    decoder.seed = seed ^ 0x5bd1e995u;
    trainer.seed = seed ^ 0x27d4eb2fu;
    if (preprocess.max_range_m <= preprocess.min_range_m) {
        throw ConfigError("preprocess.max_range_m must exceed preprocess.min_range_m");
    }
    if (sampling.samples_per_ray() < 1) {
        throw ConfigError("sampling: at least one sample per ray is needed");
    }
    check_dynamic_point_config(dynamic);
    if (crop_world_m.size() == 6) {
        for (int k = 0; k < 3; ++k) {
            if (!(crop_world_m[k] < crop_world_m[k + 3])) {
                throw ConfigError("preprocess.crop_world_m: minimum " +
                                  std::to_string(crop_world_m[k]) + " of axis " +
                                  std::to_string(k) + " must be below the maximum " +
                                  std::to_string(crop_world_m[k + 3]) +
                                  " ([xmin, ymin, zmin, xmax, ymax, zmax])");
            }
        }
    }
}

void parse_config_yaml(const std::string& text, const std::string& source, MapperConfig& config) {
    YAML::Node root;
    try {
        root = YAML::Load(text);
    } catch (const YAML::Exception& e) {
        throw ConfigError("'" + source + "' is not valid YAML: " + e.what());
    }
    if (root.IsNull()) return;
    if (!root.IsMap()) throw ConfigError("'" + source + "': the top level must be a mapping");
    auto sections = schema(config);
    for (const auto& section_node : root) {
        if (!section_node.first.IsScalar()) {
            throw ConfigError("'" + source + "': a section name must be a single word");
        }
        const std::string section_name = section_node.first.Scalar();
        auto section = std::find_if(sections.begin(), sections.end(),
                                    [&](const auto& s) { return s.first == section_name; });
        if (section == sections.end()) {
            std::string known;
            for (const auto& s : sections) known += " " + s.first;
            throw ConfigError("'" + source + "': unknown section '" + section_name +
                              "' (known:" + known + ")");
        }
        if (!section_node.second.IsMap()) {
            throw ConfigError("'" + source + "': section '" + section_name + "' must be a mapping");
        }
        for (const auto& item : section_node.second) {
            if (!item.first.IsScalar()) {
                throw ConfigError("'" + source + "': a key of section '" + section_name +
                                  "' must be a single word");
            }
            const std::string key = item.first.Scalar();
            auto field = std::find_if(section->second.begin(), section->second.end(),
                                      [&](const auto& f) { return f.first == key; });
            const std::string full = section_name + "." + key;
            if (field == section->second.end()) {
                throw ConfigError("'" + source + "': unknown key '" + full + "'");
            }
            try {
                field->second.read(item.second, full);
            } catch (const ConfigError& e) {
                throw ConfigError("'" + source + "': " + e.what());
            }
            config.mark_set(full);
        }
    }
}

void load_config_yaml(const std::filesystem::path& path, MapperConfig& config) {
    std::ifstream in(path);
    if (!in) throw ConfigError("cannot open config file '" + path.string() + "'");
    std::stringstream text;
    text << in.rdbuf();
    parse_config_yaml(text.str(), path.string(), config);
}

std::string config_to_yaml(const MapperConfig& config) {
    MapperConfig copy = config;
    YAML::Emitter out;
    out.SetFloatPrecision(6);
    out.SetDoublePrecision(12);
    out << YAML::BeginMap;
    for (auto& section : schema(copy)) {
        out << YAML::Key << section.first << YAML::Value << YAML::BeginMap;
        for (auto& field : section.second) {
            out << YAML::Key << field.first << YAML::Value;
            field.second.write(out);
        }
        out << YAML::EndMap;
    }
    out << YAML::EndMap;
    return std::string(out.c_str()) + "\n";
}

}  // namespace shine
