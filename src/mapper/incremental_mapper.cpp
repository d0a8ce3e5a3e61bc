#include "shine/mapper/incremental_mapper.hpp"

#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "shine/core/error.hpp"
#include "shine/core/median.hpp"
#include "shine/core/per_point_values.hpp"
#include "shine/core/stopwatch.hpp"
#include "shine/geometry/map_frame.hpp"
#include "shine/geometry/voxel_groups.hpp"
#include "shine/io/binary_stream.hpp"
#include "shine/io/preprocess.hpp"
#include "shine/mapper/checkpoint.hpp"
#include "shine/mapper/map_budget.hpp"
#include "shine/mapper/scan_in_map.hpp"
#include "shine/mapper/trainer.hpp"
#include "shine/model/decoder_file.hpp"
#include "shine/model/map_file.hpp"
#include "shine/optim/cosine_decay.hpp"
#include "shine/sampling/ray_set.hpp"
#include "shine/sampling/surface_normals.hpp"

namespace shine {
namespace {
#if defined(__GLIBC__)
/// Scans between two hand-backs of the heap's free pages to the system (glibc's malloc_trim).
constexpr std::size_t kTrimEveryScans = 25;
#endif
std::string shape_string(int input_dim, const std::vector<int>& hidden) {
    std::string s = std::to_string(input_dim);
    for (int h : hidden) s += " -> " + std::to_string(h);
    return s + " -> 1";
}
}  // namespace

Decoder load_incremental_decoder(const MapperConfig& config_in) {
    MapperConfig config = config_in;
    config.finalize();
    const std::string& source = config.incremental.decoder_weights;
    if (source == "none") return Decoder(config.decoder);
    Decoder decoder;
    if (source == "builtin") {
        // Outdoors at leaves finer than the street's, the decoder pretrained at 0.1 m: on the
        // real walk at 0.1 m 78.97 -> 82.75 % of held-out rays within 10 cm, the streets within
        // 0.2 points (docs/incremental.md); at 0.2 m it costs the street 0.75 points.
        const bool fine = config.fine_outdoor_leaf();
        const std::string file =
            fine ? "models/decoder_pretrained_fine.yaml" : "models/decoder_pretrained.yaml";
        const std::string text = fine ? builtin_fine_decoder_yaml() : builtin_decoder_yaml();
        if (text.empty()) {
            throw ConfigError(
                "incremental.decoder_weights is 'builtin', but this build has no " + file +
                " (it was missing when the build was configured); run `" +
                (fine ? "shine pretrain --leaf-size-m 0.1 --iterations 6000 -c "
                        "models/pretrain_fine.yaml -o " +
                            file
                      : "shine pretrain -o " + file) +
                "` and rebuild, or set incremental.decoder_weights to a decoder file");
        }
        decoder = decoder_from_yaml(text, fine ? "the built-in decoder pretrained at 0.1 m"
                                               : "the built-in pretrained decoder");
    } else if (std::filesystem::path(source).extension() == ".vdb") {
        // The decoder a batch run trained together with its features (a map.vdb).
        decoder = load_neural_map(source).sdf.decoder;
    } else {
        decoder = load_decoder(source);
    }
    if (decoder.config().input_dim != config.decoder.input_dim ||
        decoder.config().hidden_dims != config.decoder.hidden_dims) {
        throw ConfigError(
            "incremental.decoder_weights '" + source + "' is a " +
            shape_string(decoder.config().input_dim, decoder.config().hidden_dims) +
            " decoder, but the configuration asks for " +
            shape_string(config.decoder.input_dim, config.decoder.hidden_dims) +
            " (map.feature_dim, decoder.hidden_dims); pretrain a decoder of that shape with "
            "`shine pretrain -c CONFIG -o FILE` or set incremental.decoder_weights: none");
    }
    return decoder;
}

void apply_incremental_defaults(MapperConfig& config) {
    if (!config.fine_outdoor_leaf()) return;
    const IncrementalConfig defaults;
    IncrementalConfig& inc = config.incremental;
    if (config.holds_default("incremental.iterations_per_frame", inc.iterations_per_frame,
                             defaults.iterations_per_frame)) {
        inc.iterations_per_frame = 15;
    }
    // Normals over the 0.2 m map's neighbourhood: its radius (the leaf-following default halves
    // it at 0.1 m) and about as many of the denser points.
    const double street_radius_m = MapperConfig().normals.max_radius_m;
    if (!config.is_set("sampling.normal_radius_m") &&
        config.normals.max_radius_m < street_radius_m) {
        config.normals.max_radius_m = static_cast<float>(street_radius_m);
    }
    if (config.holds_default("incremental.normal_neighbors", inc.normal_neighbors,
                             defaults.normal_neighbors)) {
        inc.normal_neighbors = 24;
    }
    // The consolidation of a map with about four times the rows: twice the steps, half the
    // learning rate (real walk at 0.1 m: 88.46 / 87.81 -> 88.69 / 88.01 % of held-out rays
    // within 10 cm, every 3rd / 2nd scan held out; docs/incremental.md).
    if (config.holds_default("incremental.consolidation_steps", inc.consolidation_steps,
                             defaults.consolidation_steps)) {
        inc.consolidation_steps = 2 * defaults.consolidation_steps;
    }
    if (config.holds_default("incremental.consolidation_learning_rate",
                             inc.consolidation_learning_rate,
                             defaults.consolidation_learning_rate)) {
        inc.consolidation_learning_rate = 0.5f * defaults.consolidation_learning_rate;
    }
    // The consolidation trains on every point of the kept scans, grouped by voxel, as batch mode
    // does at these leaves (apply_batch_defaults); the scans' own steps still train on one point
    // per voxel. 30 % of its rays are drawn over the points (batch mode: 70 %): on the real walk
    // the held-out median 2.369 / 2.394 -> 2.276 / 2.289 cm (every 3rd / 2nd scan held out), the
    // streets 96.65 / 96.55 / 96.78 -> 96.61 / 96.48 / 96.66 %; at 50 or 70 % they fall below the
    // 0.2 m maps (docs/heldout.md).
    if (!config.is_set("preprocess.voxel_points")) {
        config.preprocess.voxel_points = VoxelPoints::kAll;
    }
    if (!config.is_set("sampling.every_point_share")) config.sampling.every_point_share = 0.3f;
}

IncrementalMapper::IncrementalMapper(const MapperConfig& config) : config_(config) {
    config_.finalize();
    apply_incremental_defaults(config_);
    const IncrementalConfig& inc = config_.incremental;
    if (inc.iterations_per_frame < 1) {
        throw ConfigError("incremental.iterations_per_frame must be at least 1");
    }
    if (inc.importance_ray_stride < 1) {
        throw ConfigError("incremental.importance_ray_stride must be at least 1");
    }
    if (inc.replay_frames < 1) {
        throw ConfigError("incremental.replay_frames must be at least 1, got " +
                          std::to_string(inc.replay_frames));
    }
    if (!(inc.replay_current_share >= 0.0f && inc.replay_current_share <= 1.0f)) {
        throw ConfigError("incremental.replay_current_share must be between 0 and 1, got " +
                          std::to_string(inc.replay_current_share));
    }
    if (inc.normal_window_frames < 1) {
        throw ConfigError("incremental.normal_window_frames must be at least 1");
    }
    sdf_ = std::make_unique<NeuralSdf>(config_.octree, config_.decoder);
    sdf_->decoder = load_incremental_decoder(config_);
    // The paper keeps a pretrained decoder fixed in incremental mode: a decoder that moved with
    // every scan would change the SDF of every earlier region at once.
    if (inc.decoder_weights != "none") config_.trainer.train_decoder = false;
    if (inc.consolidation_steps < 0) {
        throw ConfigError("incremental.consolidation_steps must be >= 0, got " +
                          std::to_string(inc.consolidation_steps));
    }
    if (!(inc.consolidation_learning_rate > 0.0f)) {
        throw ConfigError("incremental.consolidation_learning_rate must be positive");
    }
    if (inc.consolidation_free_samples < 0 || inc.consolidation_free_samples > 32 ||
        config_.sampling.surface_samples + inc.consolidation_free_samples < 1) {
        throw ConfigError(
            "incremental.consolidation_free_samples must be between 0 and 32 (and leave at least "
            "one sample per ray), got " +
            std::to_string(inc.consolidation_free_samples));
    }
    consolidation_band_m_ = config_.sampling.surface_band_m;
    config_.sampling.surface_band_m = inc.surface_band_m;
    config_.trainer.feature_adam.learning_rate = inc.learning_rate;
    config_.trainer.batch_size = inc.batch_size;
    config_.normals.neighbors = inc.normal_neighbors;
    if (inc.active_frames < 0) throw ConfigError("incremental.active_frames must be >= 0");
    trainer_ = std::make_unique<Trainer>(*sdf_, config_.trainer, config_.sampling);
    importance_ = ImportanceWeights(inc.importance, config_.octree.feature_dim);
    if (importance_.enabled()) trainer_->enable_anchors();
    if (config_.dynamic.enabled && config_.dynamic.motion.enabled &&
        config_.dynamic.motion.while_mapping) {
        past_motion_ =
            std::make_unique<PastMotion>(config_.dynamic.objects, config_.dynamic.motion);
    }
}

IncrementalMapper::~IncrementalMapper() = default;

void IncrementalMapper::start_from(NeuralSdf&& old, const std::string& source) {
    require_training_state("start_from");
    if (!frames_.empty() || origin_set_) {
        throw Error("IncrementalMapper::start_from after a scan: it starts an empty mapper only");
    }
    // The settings that decide the table's layout and the decoder's input: a map that differs in
    // any of them cannot be read through this run's configuration.
    const FeatureOctreeConfig& had = old.octree.config();
    const FeatureOctreeConfig& want = config_.octree;
    const auto refuse = [&](const std::string& key, const std::string& had_value,
                            const std::string& want_value) {
        throw ConfigError("cannot continue map '" + source + "': it was made with " + key + " " +
                          had_value + ", this run has " + want_value +
                          "; continue it with the settings it was made with (the same -c CONFIG "
                          "and options), or map the new data into a new map");
    };
    const auto number = [](double value) {
        std::ostringstream text;
        text << value;
        return text.str();
    };
    if (std::abs(had.leaf_size_m - want.leaf_size_m) > 1e-9 * want.leaf_size_m) {
        refuse("map.leaf_size_m", number(had.leaf_size_m) + " m", number(want.leaf_size_m) + " m");
    }
    if (had.num_levels != want.num_levels) {
        refuse("map.num_levels", number(had.num_levels), number(want.num_levels));
    }
    if (had.feature_dim != want.feature_dim) {
        refuse("map.feature_dim", number(had.feature_dim), number(want.feature_dim));
    }
    if (old.octree.feature_precision() != want.feature_precision) {
        refuse("map.feature_precision", to_string(old.octree.feature_precision()),
               to_string(want.feature_precision));
    }
    if (had.interpolation != want.interpolation) {
        refuse("map.interpolation", to_string(had.interpolation), to_string(want.interpolation));
    }
    const DecoderConfig& decoder = old.decoder.config();
    if (decoder.input_dim != config_.decoder.input_dim ||
        decoder.hidden_dims != config_.decoder.hidden_dims) {
        refuse("decoder.hidden_dims",
               "(a " + shape_string(decoder.input_dim, decoder.hidden_dims) + " decoder)",
               "a " + shape_string(config_.decoder.input_dim, config_.decoder.hidden_dims) +
                   " decoder");
    }
    const auto point = [&](const Eigen::Vector3d& p) {
        return "[" + number(p.x()) + ", " + number(p.y()) + ", " + number(p.z()) + "] m";
    };
    if (config_.origin_world_m.size() == 3) {
        const Eigen::Vector3d origin(config_.origin_world_m[0], config_.origin_world_m[1],
                                     config_.origin_world_m[2]);
        if ((origin - old.origin_world_m).norm() > 1e-6) {
            refuse("map.origin_world_m", point(old.origin_world_m), point(origin));
        }
    }
    *sdf_ = std::move(old);
    origin_set_ = true;
    // The old map's decoder, frozen: a decoder that moved would change the old part everywhere.
    config_.incremental.decoder_weights = source;
    config_.trainer.train_decoder = false;
    trainer_ = std::make_unique<Trainer>(*sdf_, config_.trainer, config_.sampling);
    // Every old row held with incremental.old_rows_importance (at most the cap Omega_m): the old
    // scans are gone, so their rows are anchored where they converged, loosely enough that the
    // new drive can still improve what both drives see (Eq. (5)); rows added later start at 0.
    importance_ = ImportanceWeights(config_.incremental.importance, config_.octree.feature_dim);
    start_rows_ = sdf_->octree.num_corners();
    const FeatureTable& table = sdf_->octree.features();
    const auto dim = static_cast<std::size_t>(config_.octree.feature_dim);
    start_features_.resize(start_rows_ * dim);
    for (std::size_t row = 0; row < start_rows_; ++row) {
        table.get_row(row, start_features_.data() + row * dim);
    }
    if (importance_.enabled()) {
        trainer_->enable_anchors();
        importance_ = importance_held_old_rows();
    }
}

void IncrementalMapper::restore_old_rows() {
    if (start_rows_ == 0) return;
    FeatureTable& table = sdf_->octree.features();
    const auto dim = static_cast<std::size_t>(config_.octree.feature_dim);
    tbb::parallel_for(std::size_t{0}, start_rows_, [&](std::size_t row) {
        table.set_row(row, start_features_.data() + row * dim);
    });
}

ImportanceWeights IncrementalMapper::importance_held_old_rows() const {
    ImportanceWeights weights(config_.incremental.importance, config_.octree.feature_dim);
    weights.resize(sdf_->octree.num_corners());
    std::vector<std::int32_t> rows(start_rows_);
    for (std::size_t i = 0; i < start_rows_; ++i) rows[i] = static_cast<std::int32_t>(i);
    const std::vector<float> held(start_rows_, std::min(config_.incremental.old_rows_importance,
                                                        weights.config().importance_cap));
    weights.update_importance_rows(rows, held, 1.0f);
    return weights;
}

void IncrementalMapper::preprocess_and_allocate(const Scan& scan, IncrementalFrameStats& frame) {
    require_training_state("add_scan/replay_scan");
    // 1. Preprocess into the map frame (as BatchMapper::add_scan). Keeping every point for the
    // consolidation, the scan is grouped by voxel and its own steps train on the groups' leads,
    // the points thinning keeps.
    auto start = std::chrono::steady_clock::now();
    const bool members = keeps_voxel_members();
    ScanInMap current =
        scan_in_map_frame(scan, config_, *sdf_, origin_set_, stats_.preprocess, members);
    ScanInMap grouped;
    if (members) {
        grouped = std::move(current);
        current = voxel_leads(grouped);
    }
    frame.rays = current.points_map.size();
    std::vector<FreeSpaceVotes> votes;
    if (config_.dynamic.enabled) {
        const auto vote_start = std::chrono::steady_clock::now();
        votes = drop_dynamic_points(scan, current, members ? &grouped : nullptr, frame);
        stats_.dynamic_seconds += seconds_since(vote_start);
    }
    frame.preprocess_seconds = seconds_since(start);

    // 2. Grow the map (around every point the consolidation will train on).
    start = std::chrono::steady_clock::now();
    frame.new_corners =
        sdf_->octree.allocate_cells(members ? grouped.points_map : current.points_map);
    check_map_budget(*sdf_, config_.max_map_mb, frames_.size(), scan.source);
    trainer_->on_map_grown();
    importance_.resize(sdf_->octree.num_corners());
    frame.allocate_seconds = seconds_since(start);

    window_votes_.push_back(std::move(votes));
    window_objects_.push_back(std::move(current_objects_));
    current_objects_ = {};
    window_.push_back(std::move(current));
    window_images_.push_back(std::move(current_image_));
    current_image_ = {};
    if (members) window_members_.push_back(std::move(grouped));
    window_normals_.emplace_back();
    // The window holds the scans the normals and the replay need, the current one last.
    const std::size_t window_frames = static_cast<std::size_t>(
        std::max(config_.incremental.normal_window_frames, config_.incremental.replay_frames));
    while (window_.size() > window_frames) {
        window_.pop_front();
        // The image's buffers are recycled for the next scan's (spare_image_), rather than
        // fresh buffers of a slightly different size each scan, allocated on a worker thread
        // and held for replay_frames scans.
        spare_image_ = std::move(window_images_.front().second);
        window_images_.pop_front();
        if (!window_members_.empty()) window_members_.pop_front();
        ++window_first_serial_;
        window_normals_.pop_front();
        window_votes_.pop_front();
        window_objects_.pop_front();
    }
#if defined(__GLIBC__)
    // Each scan allocates and frees megabytes of points, votes and images on several threads,
    // and glibc keeps the freed pages in its arenas: the 4 km city's peak RSS, at the end of the
    // mapping, varied from 1.76 to 2.18 GB between runs with the same poses; 1.76-1.77 GB in three
    // runs with the free pages handed back every 25 scans, 6 ms a time (docs/odometry.md).
    if ((frames_.size() + 1) % kTrimEveryScans == 0) malloc_trim(0);
#endif
}

bool IncrementalMapper::keeps_scan_images() const {
    const DynamicPointConfig& dynamic = config_.dynamic;
    return dynamic.enabled && dynamic.far_vote_frames > dynamic.vote_frames &&
           dynamic.objects.min_dynamic_share > 0.0f && config_.incremental.consolidation_steps > 0;
}

void IncrementalMapper::add_old_viewpoints(
    std::vector<std::pair<Eigen::Isometry3f, RangeImage>> viewpoints) {
    for (auto& viewpoint : viewpoints) old_viewpoints_.push_back(std::move(viewpoint));
}

std::size_t IncrementalMapper::vote_among_kept_scans() {
    const DynamicPointConfig& dynamic = config_.dynamic;
    const std::size_t n = window_.size();
    const bool votes_on = keeps_scan_images() && window_images_.size() == n;
    const bool motion_on =
        dynamic.enabled && dynamic.motion.enabled && config_.incremental.consolidation_steps > 0;
    const std::size_t kept =
        std::min<std::size_t>(n, static_cast<std::size_t>(config_.incremental.replay_frames));
    const std::size_t first = n - kept;
    const auto near_frames = static_cast<std::size_t>(dynamic.vote_frames);
    const auto far_frames = static_cast<std::size_t>(dynamic.far_vote_frames);
    // Fresh votes from both sides (the scans' own votes came from the scans before them only).
    std::vector<std::vector<FreeSpaceVotes>> votes(n);
    for (std::size_t w = first; votes_on && w < n; ++w) {
        votes[w].resize(window_[w].points_map.size());
    }
    for (std::size_t v = first; votes_on && v < n; ++v) {
        if (window_images_[v].second.empty()) continue;
        RangeImage image = window_images_[v].second;
        image.prepare_window(dynamic.window_bins);
        const Eigen::Isometry3f& T_sensor_map = window_images_[v].first;
        const std::size_t lo = v > first + far_frames ? v - far_frames : first;
        const std::size_t hi = std::min(n, v + far_frames + 1);
        tbb::parallel_for(lo, hi, [&](std::size_t w) {
            if (w == v || votes[w].empty()) return;
            const std::size_t apart = w > v ? w - v : v - w;
            add_free_space_votes(image, T_sensor_map, window_[w].points_map.data(),
                                 window_[w].points_map.size(), dynamic, votes[w].data(),
                                 apart > near_frames);
        });
    }
    // A continued map's old drive votes too, from every viewpoint: as a near scan where it is no
    // farther from the scan than the scan's own near scans are, else as a far scan.
    if (votes_on && !old_viewpoints_.empty()) {
        std::vector<float> near_reach_m(n, 0.0f);
        for (std::size_t w = first; w < n; ++w) {
            const std::size_t lo = w > first + near_frames ? w - near_frames : first;
            const std::size_t hi = std::min(n, w + near_frames + 1);
            for (std::size_t v = lo; v < hi; ++v) {
                near_reach_m[w] = std::max(near_reach_m[w],
                                           (window_[v].origin_map - window_[w].origin_map).norm());
            }
        }
        for (auto& viewpoint : old_viewpoints_) {
            // Named references, not a structured binding: a lambda may not capture one in C++17.
            const Eigen::Isometry3f& T_sensor_map = viewpoint.first;
            RangeImage& image = viewpoint.second;
            if (image.empty()) continue;
            image.prepare_window(dynamic.window_bins);
            const Eigen::Vector3f origin_map = T_sensor_map.inverse().translation();
            tbb::parallel_for(first, n, [&](std::size_t w) {
                if (votes[w].empty()) return;
                const bool far = (origin_map - window_[w].origin_map).norm() > near_reach_m[w];
                add_free_space_votes(image, T_sensor_map, window_[w].points_map.data(),
                                     window_[w].points_map.size(), dynamic, votes[w].data(), far);
            });
        }
    }
    old_viewpoints_.clear();
    // The images have cast their votes, and the motion test's cells and the consolidation's rays
    // are among the run's largest arrays: the images' memory, and the pages the heap holds free,
    // go back first. Scans added after this bring their own images; the ones emptied here vote
    // no more.
    for (auto& [T_sensor_map, image] : window_images_) image = RangeImage();
    spare_image_ = RangeImage();
#if defined(__GLIBC__)
    malloc_trim(0);
#endif
    if (!votes_on && !motion_on) return 0;
    // The objects that move between the kept scans (moving_objects.hpp), all of them known now.
    std::vector<std::vector<std::uint8_t>> moving;
    if (motion_on) {
        std::vector<const std::vector<Eigen::Vector3f>*> scans;
        for (std::size_t w = first; w < n; ++w) scans.push_back(&window_[w].points_map);
        MovingObjectStats motion;
        moving = find_moving_points(scans, dynamic.objects, dynamic.motion, &motion);
        stats_.moving_objects += motion.moving_objects;
    }
    std::size_t dropped = 0;
    for (std::size_t w = first; w < n; ++w) {
        std::vector<Eigen::Vector3f>& points = window_[w].points_map;
        ScanObjects& scan_objects = window_objects_[w];
        const bool with_objects = scan_objects.object_of.size() == points.size();
        const bool with_votes = votes_on && with_objects;
        const std::vector<std::uint8_t>* moved = motion_on ? &moving[w - first] : nullptr;
        if (!with_votes && moved == nullptr) continue;
        // Only the points of compact objects: the far viewpoints vote free on ground and walls
        // seen at grazing angles, which the scans' own votes had kept (docs/movers.md).
        std::vector<std::uint8_t> flags(points.size(), 0);
        for (std::size_t i = 0; with_votes && i < points.size(); ++i) {
            flags[i] = scan_objects.object_of[i] != ScanObjects::kNoObject &&
                       is_dynamic(votes[w][i], dynamic);
        }
        if (with_votes) {
            stats_.dynamic_objects +=
                spread_dynamic_to_objects(scan_objects, flags, dynamic.objects).objects_dynamic;
        }
        if (moved != nullptr) {
            for (std::size_t i = 0; i < points.size(); ++i) flags[i] |= (*moved)[i];
        }
        if (!window_members_.empty()) drop_voxel_runs(window_members_[w], flags);
        dropped += drop_flagged(flags, points, window_votes_[w], window_normals_[w],
                                window_[w].point_origins_map, window_[w].point_intensity,
                                scan_objects.object_of);
    }
    stats_.dynamic_points_dropped += dropped;
    // The replayed rays are assembled anew from the thinned scans.
    if (dropped > 0) replay_.clear();
    return dropped;
}

bool IncrementalMapper::keeps_voxel_members() const {
    return config_.preprocess.voxel_points == VoxelPoints::kAll &&
           config_.preprocess.voxel_downsample_m > 0.0;
}

std::vector<FreeSpaceVotes> IncrementalMapper::drop_dynamic_points(const Scan& scan,
                                                                   ScanInMap& current,
                                                                   ScanInMap* current_members,
                                                                   IncrementalFrameStats& frame) {
    const DynamicPointConfig& dynamic = config_.dynamic;
    const Eigen::Isometry3f T_sensor_map =
        map_from_sensor(scan.T_world_sensor, sdf_->origin_world_m).inverse().cast<float>();
    // Three independent steps, side by side (the objects' search is serial): the scan's range
    // image, with which it votes on the points of the scans before it; the scan's own points,
    // voted on by the scans before it; and the scan's compact objects (dynamic_objects.hpp),
    // over which each point's own votes are spread and which the scan keeps while the scans
    // after it vote on its points.
    RangeImage image;
    std::vector<FreeSpaceVotes> votes(current.points_map.size());
    std::vector<std::uint8_t> moving;
    const bool objects = dynamic.objects.min_dynamic_share > 0.0f;
    tbb::parallel_invoke(
        [&] {
            image = RangeImage(scan.points_sensor);
            // Kept without its window for the votes before the consolidation (a third of the
            // memory; prepared again then, one image at a time).
            if (keeps_scan_images()) {
                current_image_.first = T_sensor_map;
                std::swap(current_image_.second, spare_image_);  // spare_image_ now empty
                current_image_.second = image;  // into the recycled buffers where they fit
            }
            image.prepare_window(dynamic.window_bins);  // asked for the points of many scans
        },
        [&] {
            if (votes.empty()) return;
            for (const auto& [T_past_map, past_image] : voters_) {
                add_free_space_votes(past_image, T_past_map, current.points_map.data(),
                                     current.points_map.size(), dynamic, votes.data());
            }
        },
        [&] {
            if (objects) current_objects_ = find_scan_objects(current.points_map, dynamic.objects);
        },
        [&] {
            // Objects that moved over the scans before (moving_objects.hpp), before they train.
            if (past_motion_) {
                MovingObjectStats motion;
                moving = past_motion_->add_scan(current.points_map, &motion);
                stats_.moving_objects += motion.moving_objects;
            }
        });
    const auto dynamic_flags = [&](const ScanObjects* scan_objects,
                                   const std::vector<FreeSpaceVotes>& point_votes,
                                   const std::vector<std::uint8_t>* also) {
        std::vector<std::uint8_t> flags(point_votes.size());
        for (std::size_t i = 0; i < point_votes.size(); ++i) {
            flags[i] = is_dynamic(point_votes[i], dynamic) ? 1 : 0;
        }
        if (also != nullptr && also->size() == flags.size()) {
            for (std::size_t i = 0; i < flags.size(); ++i) flags[i] |= (*also)[i];
        }
        if (scan_objects) {
            stats_.dynamic_objects +=
                spread_dynamic_to_objects(*scan_objects, flags, dynamic.objects).objects_dynamic;
        }
        return flags;
    };
    const std::vector<std::uint8_t> current_dynamic =
        dynamic_flags(objects ? &current_objects_ : nullptr, votes, &moving);
    if (current_members) drop_voxel_runs(*current_members, current_dynamic);
    frame.dynamic_dropped =
        drop_flagged(current_dynamic, current.points_map, current.point_origins_map,
                     current.point_intensity, current_objects_.object_of, votes);
    // The points of the normal window's scans that this scan sees through are dropped (with their
    // normals), so that replay and the normals of later scans no longer use them. Older replayed
    // scans had as many scans after them to vote.
    const std::size_t normal_scans =
        std::min<std::size_t>(window_.size(), config_.incremental.normal_window_frames);
    for (std::size_t w = window_.size() - normal_scans; w < window_.size(); ++w) {
        std::vector<Eigen::Vector3f>& points = window_[w].points_map;
        std::vector<Eigen::Vector3f>& origins = window_[w].point_origins_map;
        std::vector<float>& intensity = window_[w].point_intensity;
        std::vector<FreeSpaceVotes>& past_votes = window_votes_[w];
        std::vector<Eigen::Vector3f>& normals = window_normals_[w];
        if (points.empty() || past_votes.size() != points.size()) continue;
        add_free_space_votes(image, T_sensor_map, points.data(), points.size(), dynamic,
                             past_votes.data());
        ScanObjects& past_objects = window_objects_[w];
        const bool with_objects = objects && past_objects.object_of.size() == points.size();
        const std::vector<std::uint8_t> past_dynamic =
            dynamic_flags(with_objects ? &past_objects : nullptr, past_votes, nullptr);
        if (!window_members_.empty()) drop_voxel_runs(window_members_[w], past_dynamic);
        frame.dynamic_forgotten += drop_flagged(past_dynamic, points, past_votes, normals, origins,
                                                intensity, past_objects.object_of);
    }
    stats_.dynamic_points_dropped += frame.dynamic_dropped + frame.dynamic_forgotten;
    voters_.emplace_back(T_sensor_map, std::move(image));
    while (voters_.size() > static_cast<std::size_t>(dynamic.vote_frames)) voters_.pop_front();
    return votes;  // the kept points' votes so far; the scans after it add theirs
}

void IncrementalMapper::estimate_current_normals(IncrementalFrameStats& frame) {
    const std::size_t n = window_.size();
    // 3. Normals of the current scan, among the endpoints of the last normal_window_frames scans;
    // the replayed scans keep the ones they got when they were current.
    const auto start = std::chrono::steady_clock::now();
    if (config_.normals.enabled) {
        const std::size_t normal_scans =
            std::min<std::size_t>(n, config_.incremental.normal_window_frames);
        RaySet neighbours;
        for (std::size_t w = n - normal_scans; w < n; ++w) {
            neighbours.add_scan(window_[w].origin_map, window_[w].points_map);
        }
        const std::size_t begin =
            neighbours.first_ray(static_cast<std::uint32_t>(normal_scans - 1));
        const std::size_t end = neighbours.num_rays();
        const std::vector<Eigen::Vector3f> normals =
            end > begin ? estimate_ray_normals(neighbours, config_.normals, begin, end)
                        : std::vector<Eigen::Vector3f>(end, Eigen::Vector3f::Zero());
        for (std::size_t r = begin; r < end; ++r) {
            frame.rays_with_normal += normals[r].squaredNorm() > 0.5f;
        }
        window_normals_.back().assign(normals.begin() + static_cast<std::ptrdiff_t>(begin),
                                      normals.end());
    }
    frame.normals_seconds = seconds_since(start);
}

void IncrementalMapper::sync_replay_rays(std::size_t changed_scans) {
    replay_.sync(window_, window_normals_, window_first_serial_,
                 static_cast<std::size_t>(config_.incremental.replay_frames), changed_scans);
}

void IncrementalMapper::move_kept_scans(const std::vector<Eigen::Isometry3d>& corrections) {
    const auto move = [](ScanInMap& scan, const Eigen::Isometry3f& T) {
        scan.origin_map = T * scan.origin_map;
        for (Eigen::Vector3f& p : scan.points_map) p = T * p;
        for (Eigen::Vector3f& o : scan.point_origins_map) o = T * o;
    };
    for (std::size_t k = 0; k < corrections.size(); ++k) {
        const Eigen::Isometry3f T = corrections[k].cast<float>();
        const std::size_t w = window_.size() - corrections.size() + k;
        move(window_[w], T);
        if (!window_members_.empty()) move(window_members_[w], T);
        for (Eigen::Vector3f& n : window_normals_[w]) n = T.linear() * n;
    }
    replay_.clear();
}

RaySet IncrementalMapper::kept_scans_every_point() const {
    RaySet rays;
    const std::size_t kept = std::min<std::size_t>(
        window_members_.size(), static_cast<std::size_t>(config_.incremental.replay_frames));
    std::vector<Eigen::Vector3f> normals;
    for (std::size_t w = window_members_.size() - kept; w < window_members_.size(); ++w) {
        const ScanInMap& scan = window_members_[w];
        rays.add_scan(scan.origin_map, scan.points_map, scan.voxel_begin, scan.point_origins_map);
        // Each voxel's points share the normal its lead got (the thinned scans' normals).
        const std::vector<Eigen::Vector3f>& lead_normals = window_normals_[w];
        const bool with_normals = lead_normals.size() == scan.voxel_begin.size();
        for_each_point_run(
            scan.points_map.size(), scan.voxel_begin, [&](std::size_t, std::size_t run) {
                normals.push_back(with_normals ? lead_normals[run] : Eigen::Vector3f::Zero());
            });
    }
    rays.set_normals(std::move(normals));
    return rays;
}

void IncrementalMapper::replay_scan(const Scan& scan) {
    IncrementalFrameStats frame;
    preprocess_and_allocate(scan, frame);
    if (config_.incremental.replay_frames > 1) {
        // The replayed scans' normals are trained on again by the next scans: estimate them as
        // when the scan was current, so that a resumed run trains exactly as an uninterrupted one.
        estimate_current_normals(frame);
    }
    frames_.push_back(frame);  // compared with the stored frames by load_state()
}

const IncrementalFrameStats& IncrementalMapper::add_scan_untrained(const Scan& scan) {
    const auto frame_start = std::chrono::steady_clock::now();
    IncrementalFrameStats frame;
    frame.trained = false;
    preprocess_and_allocate(scan, frame);
    estimate_current_normals(frame);
    frame.total_seconds = seconds_since(frame_start);
    frame.stages[Stage::kPreprocess] =
        frame.total_seconds - frame.allocate_seconds - frame.normals_seconds;
    frame.stages[Stage::kAllocate] = frame.allocate_seconds;
    frame.stages[Stage::kNormals] = frame.normals_seconds;
    stats_.load_seconds += frame.preprocess_seconds;
    stats_.allocate_seconds += frame.allocate_seconds;
    stats_.normals_seconds += frame.normals_seconds;
    ++stats_.frames;
    stats_.rays += frame.rays;
    frames_.push_back(frame);
    return frames_.back();
}

const ConsolidationStats& IncrementalMapper::consolidate(
    int steps, const std::function<void(int, int)>& progress, const PoseRefinementConfig* refine) {
    require_training_state("consolidate");
    if (steps < 0) {
        throw ConfigError("consolidation steps must be >= 0, got " + std::to_string(steps));
    }
    const auto start = std::chrono::steady_clock::now();
    consolidation_ = ConsolidationStats{};
    if (steps == 0 || window_.empty()) return consolidation_;
    // The kept scans vote on each other first: a mover seen far ahead, or a parked car that
    // left, is seen through only by scans that came later or from farther than the scans'
    // own votes reached.
    const auto vote_start = std::chrono::steady_clock::now();
    consolidation_.dynamic_dropped = vote_among_kept_scans();
    consolidation_.vote_seconds = seconds_since(vote_start);
    // The kept scans: every point of each, grouped by voxel, or the points their steps used.
    RaySet every_point;
    const RaySet* kept_rays = &every_point;
    std::size_t ray_begin = 0;
    std::size_t kept_scans = 0;
    const std::size_t replayed = static_cast<std::size_t>(config_.incremental.replay_frames);
    const bool refining = refine && refine->rounds > 0 && std::min(window_.size(), replayed) >= 3;
    if (window_members_.empty() && refining) {
        // The rounds move the rays: a set of the kept scans of its own, assembled afresh.
        ReplayRays kept;
        kept.sync(window_, window_normals_, window_first_serial_, replayed, replayed);
        every_point = kept.rays();
        kept_scans = every_point.num_scans();
    } else if (window_members_.empty()) {
        sync_replay_rays(0);  // after a resume at the end of the sequence: assembled here
        kept_rays = &replay_.rays();
        ray_begin = replay_.begin_ray();
        kept_scans = replay_.live_scans();
    } else {
        every_point = kept_scans_every_point();
        kept_scans = every_point.num_scans();
    }
    const RaySet& rays = *kept_rays;
    if (rays.num_rays() == ray_begin) return consolidation_;
    consolidation_.scans = kept_scans;
    consolidation_.rays = rays.num_rays() - ray_begin;
    consolidation_.voxels =
        rays.group_at_or_after(rays.num_rays()) - rays.group_at_or_after(ray_begin);
    consolidation_.surface_band_m = consolidation_band_m_;

    // A fresh optimiser: Adam's moments and step counts from the scans' short runs at their
    // higher learning rate are dropped (every row's state reads as zero again; the next scan
    // takes new anchors). On the streets this scores 0.1-0.2 points above carrying them on.
    trainer_->begin_scan();
    trainer_->release_inactive_state(1);
    restore_old_rows();
    trainer_->set_surface_band_m(consolidation_band_m_);
    // As many rays per step as the scans' steps, with more free-space samples on each.
    const SamplingConfig& scans_sampling = config_.sampling;
    const int rays_per_step =
        std::max(1, config_.trainer.batch_size / scans_sampling.samples_per_ray());
    consolidation_.free_samples = config_.incremental.consolidation_free_samples;
    consolidation_.batch_size =
        rays_per_step * (scans_sampling.surface_samples + consolidation_.free_samples);
    trainer_->set_free_samples_and_batch_size(consolidation_.free_samples,
                                              consolidation_.batch_size);
    const float lr0 = config_.incremental.consolidation_learning_rate;
    const double final_ratio = config_.final_learning_rate_ratio;
    // A continued map (start_from): the kept scans are the new drive's only, and the rows they
    // share with the old part (the coarse levels above all) would otherwise be fitted to them
    // alone. The old rows stay at the cap, anchored at their saved values (restored above); the
    // new rows are free, as in a consolidation of a map of its own.
    ImportanceWeights old_rows;
    if (start_rows_ > 0 && importance_.enabled()) old_rows = importance_held_old_rows();
    const ImportanceWeights* regularizer = old_rows.num_rows() > 0 ? &old_rows : nullptr;
    // Pose refinement: each kept scan's place, as a pose (its sensor's origin, the map's axes),
    // before and after the rounds.
    std::vector<Eigen::Isometry3d> places_before, places;
    if (refining) {
        for (std::uint32_t k = 0; k < every_point.num_scans(); ++k) {
            Eigen::Isometry3d place = Eigen::Isometry3d::Identity();
            place.translation() = every_point.origin_of_scan(k).cast<double>();
            places_before.push_back(place);
        }
        places = places_before;
    }
    const auto run_rounds = [&](int step) {
        while (refining && static_cast<int>(consolidation_.refinement.size()) < refine->rounds &&
               refine->round_step(static_cast<int>(consolidation_.refinement.size()), steps) <=
                   step) {
            PoseRefinementRound round;
            std::vector<Eigen::Isometry3d> refined =
                refine_scan_poses(*sdf_, every_point, places, *refine,
                                  static_cast<int>(consolidation_.refinement.size()), &round);
            move_scans(every_point, places, refined);
            places = std::move(refined);
            round.step = step;
            consolidation_.refinement.push_back(round);
        }
    };
    TrainStepStats last;
    for (int it = 0; it < steps; ++it) {
        run_rounds(it);
        const double ratio = cosine_decay_ratio(it, steps, final_ratio);
        trainer_->set_feature_learning_rate(static_cast<float>(lr0 * ratio));
        // No focus: every kept scan weighs the same, as in batch mode; no regulariser but the
        // old map's above.
        last = trainer_->step(rays, ray_begin, rays.num_rays(), iteration_++, regularizer);
        if (progress) progress(it + 1, steps);
    }
    if (refining) {
        for (std::size_t k = 0; k < places.size(); ++k) {
            consolidation_.corrections_map.push_back(places[k] * places_before[k].inverse());
        }
        move_kept_scans(consolidation_.corrections_map);
    }
    trainer_->set_surface_band_m(config_.sampling.surface_band_m);
    trainer_->set_free_samples_and_batch_size(scans_sampling.free_samples,
                                              config_.trainer.batch_size);
    trainer_->set_feature_learning_rate(config_.trainer.feature_adam.learning_rate);
    consolidation_.steps = steps;
    consolidation_.bce = last.bce;
    consolidation_.seconds = seconds_since(start);
    stats_.iterations += static_cast<std::size_t>(steps);
    stats_.final_bce = last.bce;
    stats_.final_eikonal = last.eikonal;
    stats_.train_seconds += consolidation_.seconds;
    return consolidation_;
}

const IncrementalFrameStats& IncrementalMapper::add_scan(const Scan& scan, int step_scans) {
    if (step_scans < 1) throw std::invalid_argument("add_scan: step_scans must be at least 1");
    const auto frame_start = std::chrono::steady_clock::now();
    IncrementalFrameStats frame;
    preprocess_and_allocate(scan, frame);

    estimate_current_normals(frame);
    // The training rays: the last replay_frames scans with their normals, the current scan last.
    // The scans the dynamic filter just thinned (the last normal_window_frames before the current
    // one) are taken anew.
    sync_replay_rays(static_cast<std::size_t>(config_.incremental.normal_window_frames) + 1);
    const RaySet& rays = replay_.rays();
    const std::size_t replay_begin = replay_.begin_ray();
    const std::size_t ray_begin = replay_.last_scan_begin_ray();
    const std::size_t ray_end = rays.num_rays();
    const RayFocus focus{ray_begin, config_.incremental.replay_current_share};

    // 4. Train on the current scan (and the replayed ones before it).
    auto start = std::chrono::steady_clock::now();
    trainer_->reset_seconds();
    trainer_->begin_scan();
    const ImportanceWeights* regularizer = importance_.enabled() ? &importance_ : nullptr;
    if (ray_end > ray_begin) {
        TrainStepStats last;
        const int iterations = config_.incremental.iterations_per_frame * step_scans;
        const float lr0 = config_.trainer.feature_adam.learning_rate;
        // Each scan's training ends with small steps (cosine decay to final_learning_rate_ratio,
        // as batch mode over its whole run), so that the anchors theta* are converged values.
        const double final_ratio = config_.final_learning_rate_ratio;
        for (int it = 0; it < iterations; ++it) {
            const double ratio = cosine_decay_ratio(it, iterations, final_ratio);
            trainer_->set_feature_learning_rate(static_cast<float>(lr0 * ratio));
            last = trainer_->step(rays, replay_begin, ray_end, iteration_++, regularizer, focus);
        }
        frame.bce = last.bce;
        frame.regularization = last.regularization;
        stats_.final_bce = last.bce;
        stats_.final_eikonal = last.eikonal;
        stats_.iterations += static_cast<std::size_t>(iterations);
    }
    frame.train_seconds = seconds_since(start);

    // 5. Importance of this scan's data (Eq. (4)) and the new anchors.
    start = std::chrono::steady_clock::now();
    if (regularizer && ray_end > ray_begin) {
        RowGradientNormSums sums;
        const std::size_t samples = trainer_->accumulate_bce_gradient_norms(
            rays, ray_begin, ray_end, frames_.size(), sums,
            static_cast<std::size_t>(config_.incremental.importance_ray_stride), replay_begin);
        // The paper's sum over the scan's samples, divided by their number N: with the mean BCE
        // of a batch as the data loss, lambda_r * Omega is then on the scale of the data
        // gradient whatever the scan's point count (see docs/incremental.md). The anchors need
        // no update: the next scan snapshots each row's value when it first touches it.
        const float inv_n = samples > 0 ? 1.0f / static_cast<float>(samples) : 1.0f;
        importance_.update_importance_rows(sums.rows, sums.sums, inv_n);
    }
    if (config_.incremental.active_frames > 0) {
        trainer_->release_inactive_state(
            static_cast<std::uint32_t>(config_.incremental.active_frames));
    }
    frame.optimizer_bytes = trainer_->optimizer_bytes();
    frame.importance_seconds = seconds_since(start);
    frame.total_seconds = seconds_since(frame_start);
    frame.stages[Stage::kPreprocess] = frame.preprocess_seconds;
    frame.stages[Stage::kAllocate] = frame.allocate_seconds;
    frame.stages[Stage::kNormals] = frame.normals_seconds;
    // The window's ray set is assembled between allocation and normals: counted as preprocessing.
    frame.stages[Stage::kPreprocess] += frame.total_seconds - frame.preprocess_seconds -
                                        frame.allocate_seconds - frame.normals_seconds -
                                        frame.train_seconds - frame.importance_seconds;
    frame.stages[Stage::kSample] = std::min(trainer_->seconds().sample, frame.train_seconds);
    frame.stages[Stage::kTrain] = frame.train_seconds - frame.stages[Stage::kSample];
    frame.stages[Stage::kImportance] = frame.importance_seconds;
    stats_.load_seconds += frame.preprocess_seconds;
    stats_.allocate_seconds += frame.allocate_seconds;
    stats_.normals_seconds += frame.normals_seconds;
    stats_.train_seconds += frame.train_seconds + frame.importance_seconds;
    ++stats_.frames;
    stats_.rays += frame.rays;
    frames_.push_back(frame);
    return frames_.back();
}

double IncrementalMapper::median_frame_seconds() const {
    std::vector<double> seconds;
    for (const auto& f : frames_) {
        if (f.trained) seconds.push_back(f.total_seconds);
    }
    return median(std::move(seconds));
}

std::size_t IncrementalMapper::state_bytes() const {
    if (!trainer_) return released_state_bytes_;
    return importance_.memory_bytes() + trainer_->optimizer_bytes();
}

void IncrementalMapper::release_training_state() {
    if (!trainer_) return;
    released_state_bytes_ = state_bytes();
    trainer_.reset();
    start_features_ = {};
    importance_ = ImportanceWeights();
    window_ = {};
    window_members_ = {};
    window_normals_ = {};
    window_votes_ = {};
    window_objects_ = {};
    voters_ = {};
    if (past_motion_) past_motion_->clear();
    window_images_ = {};
    spare_image_ = {};
    replay_ = ReplayRays();
    sdf_->octree.compact_structure();
#if defined(__GLIBC__)
    malloc_trim(0);  // hand the freed pages back, so that the products find them free
#endif
}

void IncrementalMapper::require_training_state(const char* what) const {
    if (!trainer_) {
        throw Error(std::string("IncrementalMapper::") + what +
                    " after release_training_state(): the map is final");
    }
}

void IncrementalMapper::save_state(BinaryWriter& out) const {
    require_training_state("save_state");
    if (start_rows_ > 0) {
        // A resume would rebuild the map from the new scans alone, without the old map.
        throw Error(
            "IncrementalMapper::save_state: a mapper that continues a saved map (start_from) "
            "writes no checkpoint");
    }
    out.tag("incremental mapper");
    static_assert(std::is_trivially_copyable_v<IncrementalFrameStats>);
    static_assert(std::is_trivially_copyable_v<MappingStats>);
    out.array(frames_);
    out.value(stats_);
    out.value<std::uint64_t>(iteration_);
    save_sdf_parameters(out, *sdf_);
    trainer_->save_state(out);
    importance_.save(out);
}

void IncrementalMapper::load_state(BinaryReader& in) {
    require_training_state("load_state");
    in.expect_tag("incremental mapper");
    std::vector<IncrementalFrameStats> frames = in.array<IncrementalFrameStats>("frame statistics");
    if (frames.size() != frames_.size()) {
        in.fail("frame statistics", "record " + std::to_string(frames.size()) + " frames, but " +
                                        std::to_string(frames_.size()) + " were replayed");
    }
    for (std::size_t i = 0; i < frames.size(); ++i) {
        if (frames[i].rays != frames_[i].rays || frames[i].new_corners != frames_[i].new_corners) {
            in.fail("frame statistics",
                    "of frame " + std::to_string(i) + " record " + std::to_string(frames[i].rays) +
                        " points and " + std::to_string(frames[i].new_corners) +
                        " new corners, but the scan now gives " + std::to_string(frames_[i].rays) +
                        " and " + std::to_string(frames_[i].new_corners) +
                        " (did the data or the configuration change?)");
        }
    }
    const auto stats = in.value<MappingStats>("mapping statistics");
    const auto iteration = in.value<std::uint64_t>("iteration");
    load_sdf_parameters(in, *sdf_);
    trainer_->load_state(in);
    importance_.load(in);
    if (importance_.num_rows() != sdf_->octree.num_corners()) {
        in.fail("importance weights", "cover " + std::to_string(importance_.num_rows()) +
                                          " rows, the map has " +
                                          std::to_string(sdf_->octree.num_corners()));
    }
    frames_ = std::move(frames);
    stats_ = stats;
    iteration_ = iteration;
    replay_.clear();  // assembled afresh from the replayed window by the next scan
}

}  // namespace shine
