// shinevdb.NeuralMap: the neural SDF map of `shine map`, fed from numpy arrays.
//
// Two ways to build it, the CLI's two modes:
//   - batch (`shine map`): add_scan() for every scan, then train(); the same BatchMapper calls
//     map_sequence() makes, so the same scans, configuration, seed and thread count give the
//     CLI's map bit for bit (python/tests/test_cli_parity.py);
//   - incremental (`shine map --mode incremental`): integrate() one scan at a time, each trained
//     at once with the pretrained, frozen decoder.
// A map read by NeuralMap.load() answers queries, meshes and bakes but is not trained further
// (map.vdb holds no optimiser state).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <sys/resource.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <string>

#include "long_call.hpp"
#include "mesh_colors.hpp"
#include "numpy_io.hpp"
#include "shine/bake/level_set_bake.hpp"
#include "shine/bake/level_set_file.hpp"
#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/geometry/map_frame.hpp"
#include "shine/mapper/batch_mapper.hpp"
#include "shine/mapper/incremental_mapper.hpp"
#include "shine/mapper/map_localizer.hpp"
#include "shine/mapper/map_sequence.hpp"
#include "shine/mapper/mapper_config.hpp"
#include "shine/mesh/level_set_mesh.hpp"
#include "shine/model/map_file.hpp"
#include "shine/model/sdf_gradient.hpp"

namespace shinevdb {
namespace {
namespace fs = std::filesystem;
using namespace shine;

enum class Mode { kEmpty, kBatch, kIncremental, kLoaded };

const char* mode_name(Mode mode) {
    switch (mode) {
        case Mode::kEmpty:
            return "empty";
        case Mode::kBatch:
            return "batch";
        case Mode::kIncremental:
            return "incremental";
        case Mode::kLoaded:
            return "loaded";
    }
    return "?";
}

std::string path_string(const py::handle& path) {
    return py::str(py::module_::import("os").attr("fspath")(path)).cast<std::string>();
}

class NeuralMap {
  public:
    NeuralMap(const py::object& leaf_size_m, const py::object& config, const py::object& threads) {
        if (py::isinstance<py::dict>(config)) {
            // JSON is YAML: the dict goes through the same parser as a config file.
            const std::string text =
                py::module_::import("json").attr("dumps")(config).cast<std::string>();
            parse_config_yaml(text, "the config dict", config_);
        } else if (!config.is_none()) {
            if (!py::isinstance<py::str>(config) &&
                !py::isinstance(config, py::module_::import("os").attr("PathLike"))) {
                throw py::value_error("config must be None, a dict or the path of a YAML file");
            }
            load_config_yaml(path_string(config), config_);
        }
        if (!leaf_size_m.is_none()) {
            const double leaf = leaf_size_m.cast<double>();
            if (!(leaf > 0.0) || !std::isfinite(leaf)) {
                throw py::value_error("leaf_size_m must be a positive number of metres, got " +
                                      std::to_string(leaf));
            }
            config_.octree.leaf_size_m = leaf;
        }
        if (!threads.is_none()) {
            const int n = threads.cast<int>();
            if (n < 0) throw py::value_error("threads must be >= 0 (0: all cores)");
            config_.threads = n;
        }
        config_.finalize();
    }

    static std::unique_ptr<NeuralMap> load(const py::object& path) {
        const std::string file = path_string(path);
        auto map = std::unique_ptr<NeuralMap>(new NeuralMap());
        {
            py::gil_scoped_release release;
            LoadedMap loaded = load_neural_map(file);
            parse_config_yaml(loaded.config_text, "the configuration stored in '" + file + "'",
                              map->config_);
            map->config_.finalize();
            map->loaded_ = std::make_unique<NeuralSdf>(std::move(loaded.sdf));
        }
        map->mode_ = Mode::kLoaded;
        return map;
    }

    void integrate(const py::handle& points, const py::handle& pose, const py::handle& times) {
        Scan scan = make_scan(points, pose, "points", "pose");
        if (!times.is_none()) {
            per_point_values(times, scan.points_sensor.size(), "times");
            warn_times_unused();
        }
        require_mode(Mode::kIncremental, "integrate()");
        {
            py::gil_scoped_release release;
            const auto limit = limit_threads(config_.threads);
            if (!incremental_) incremental_ = std::make_unique<IncrementalMapper>(config_);
            incremental_->add_scan(scan);
        }
        mode_ = Mode::kIncremental;
        ++scans_;
        check_signals();
    }

    void add_scan(const py::handle& points, const py::handle& pose) {
        Scan scan = make_scan(points, pose, "points", "pose");
        require_mode(Mode::kBatch, "add_scan()");
        if (batch_ && batch_->iterations_done() > 0) {
            throw std::runtime_error(
                "add_scan() after train(): batch mode trains once on all its scans; add every "
                "scan first, or use integrate() to map scan by scan");
        }
        {
            py::gil_scoped_release release;
            const auto limit = limit_threads(config_.threads);
            if (!batch_) batch_ = std::make_unique<BatchMapper>(config_);
            batch_->add_scan(scan);
        }
        mode_ = Mode::kBatch;
        ++scans_;
    }

    bool train(const py::object& steps, bool progress) {
        if (mode_ != Mode::kBatch || !batch_) {
            throw std::runtime_error(mode_ == Mode::kEmpty
                                         ? "train() needs scans: call add_scan() first"
                                         : std::string("train() is for batch mode, this map is ") +
                                               mode_name(mode_));
        }
        batch_->finish_scans();  // the dynamic-point filter, then the map the schedule follows
        const int total = batch_->planned_iterations();
        int target = total;
        if (!steps.is_none()) {
            const long long n = steps.cast<long long>();
            if (n < 0) throw py::value_error("steps must be >= 0 or None (all remaining steps)");
            target = static_cast<int>(std::min<long long>(total, batch_->iterations_done() + n));
        }
        if (batch_->iterations_done() >= target) return batch_->iterations_done() >= total;
        SignalPoll signals;
        {
            py::gil_scoped_release release;
            const auto limit = limit_threads(config_.threads);
            const auto stop = [&] { return batch_->iterations_done() >= target || signals(); };
            if (progress) {
                train_with_progress(*batch_, total, "train", stop);
            } else {
                batch_->train({}, stop);
            }
        }
        signals.rethrow();
        return batch_->iterations_done() >= total;
    }

    py::dict consolidate(const py::object& steps, bool progress) {
        if (mode_ != Mode::kIncremental || !incremental_) {
            throw std::runtime_error(
                mode_ == Mode::kEmpty
                    ? "consolidate() needs scans: call integrate() first"
                    : std::string("consolidate() is for incremental mode, this map is ") +
                          mode_name(mode_));
        }
        int n = incremental_->config().incremental.consolidation_steps;  // leaf defaults applied
        if (!steps.is_none()) {
            const long long wanted = steps.cast<long long>();
            if (wanted < 0 || wanted > 100000000) {
                throw py::value_error(
                    "steps must be 0..100000000 or None (the configuration's "
                    "incremental.consolidation_steps)");
            }
            n = static_cast<int>(wanted);
        }
        {
            py::gil_scoped_release release;
            const auto limit = limit_threads(config_.threads);
            Progress line("consolidate", static_cast<std::size_t>(n), progress);
            // The kept scans' poses refined as `shine map --mode incremental` refines them at
            // given poses (refine.in_consolidation).
            const PoseRefinementConfig refine = incremental_->config().scaled_refinement();
            const bool refining = incremental_->config().refines_in_consolidation();
            incremental_->consolidate(
                n, [&](int done, int) { line.update(static_cast<std::size_t>(done)); },
                refining ? &refine : nullptr);
            line.finish();
        }
        check_signals();
        return consolidation_dict();
    }

    py::dict consolidation_dict() const {
        const ConsolidationStats& c = incremental_->consolidation();
        py::dict out;
        out["steps"] = c.steps;
        out["scans"] = c.scans;
        out["rays"] = c.rays;
        out["surface_band_m"] = c.surface_band_m;
        out["free_samples"] = c.free_samples;
        out["voxels"] = c.voxels;
        out["batch_size"] = c.batch_size;
        out["seconds"] = c.seconds;
        out["bce"] = c.bce;
        // World-frame corrections of the kept scans (the last len(...) integrated, oldest
        // first): a kept scan's refined pose is correction @ the pose it was integrated at.
        Eigen::Isometry3d T_world_map = Eigen::Isometry3d::Identity();
        T_world_map.translation() = incremental_->sdf().origin_world_m;
        std::vector<Eigen::Isometry3d> corrections_world;
        for (const Eigen::Isometry3d& C_map : c.corrections_map) {
            corrections_world.push_back(T_world_map * C_map * T_world_map.inverse());
        }
        out["pose_corrections"] = poses_to_array(corrections_world);
        py::list rounds;
        for (const PoseRefinementRound& r : c.refinement) {
            py::dict round;
            round["step"] = r.step;
            round["accepted"] = r.accepted;
            round["rejected"] = r.rejected;
            round["median_translation_m"] = r.median_translation_m;
            round["median_rotation_deg"] = r.median_rotation_deg;
            round["seconds"] = r.seconds;
            rounds.append(round);
        }
        out["refinement"] = rounds;
        return out;
    }

    py::tuple sdf_values(const py::handle& points) const {
        const std::vector<Eigen::Vector3d> points_world = points3d(points, "points");
        const NeuralSdf& sdf = require_sdf("sdf()");
        const std::size_t n = points_world.size();
        std::vector<float> values(n, std::numeric_limits<float>::quiet_NaN());
        std::vector<float> gradients(3 * n, std::numeric_limits<float>::quiet_NaN());
        {
            py::gil_scoped_release release;
            const auto limit = limit_threads(config_.threads);
            std::vector<Eigen::Vector3f> points_map(n);
            for (std::size_t i = 0; i < n; ++i) {
                points_map[i] = (points_world[i] - sdf.origin_world_m).cast<float>();
            }
            std::vector<float> sdf_m;
            std::vector<Eigen::Vector3f> gradient_map;
            std::vector<std::uint8_t> valid;
            query_sdf_and_gradient(sdf, points_map, QueryMask::kAnyLevel, sdf_m, gradient_map,
                                   valid);
            for (std::size_t i = 0; i < n; ++i) {
                if (!valid[i]) continue;  // NaN outside the map
                values[i] = sdf_m[i];
                for (int a = 0; a < 3; ++a) gradients[3 * i + a] = gradient_map[i][a];
            }
        }
        const auto rows = static_cast<py::ssize_t>(n);
        return py::make_tuple(take_vector(std::move(values), {rows}),
                              take_vector(std::move(gradients), {rows, 3}));
    }

    py::tuple localize(const py::handle& points, const py::object& initial_pose) {
        const std::vector<Eigen::Vector3f> points_sensor = points3f(points, "points");
        const NeuralSdf& sdf = require_sdf("localize()");
        std::optional<Eigen::Isometry3d> start;
        if (!initial_pose.is_none()) start = pose_from_array(initial_pose, "initial_pose");
        LocalizeRecord record;
        {
            py::gil_scoped_release release;
            const auto limit = limit_threads(config_.threads);
            // A new track: at an initial pose, after the map changed, or for the first call.
            if (start || !localizer_ || localizer_sdf_ != &sdf || localizer_scans_ != scans_ ||
                localizer_iterations_ != iterations_done()) {
                localizer_ = std::make_unique<MapLocalizer>(sdf, LocalizeConfig{});
                localizer_sdf_ = &sdf;
                localizer_scans_ = scans_;
                localizer_iterations_ = iterations_done();
                if (start) localizer_->set_initial_pose(*start);
            }
            record = localizer_->localize(points_sensor);
        }
        py::dict info;
        info["localized"] = record.localized;
        info["source"] = to_string(record.source);
        info["points"] = record.points;
        info["valid_points"] = record.valid_points;
        info["inlier_ratio"] = record.inlier_ratio;
        info["residual_m"] = record.residual_m;
        info["condition_number"] = record.condition_number;
        info["status"] = to_string(record.status);
        info["iterations"] = record.iterations;
        info["candidates"] = record.candidates;
        info["prediction_score"] = record.prediction_score;
        info["start_score"] = record.start_score;
        info["start_motion_scale"] = record.start_motion_scale;
        info["start_yaw_deg"] = record.start_yaw_deg;
        info["seconds"] = record.seconds;
        return py::make_tuple(pose_to_array(record.T_world_sensor), info);
    }

    py::tuple extract_triangle_mesh(const py::object& voxel_size_m) const {
        const BakeConfig bake = bake_config(voxel_size_m);
        const NeuralSdf& sdf = require_sdf("extract_triangle_mesh()");
        TriangleMesh mesh;
        {
            py::gil_scoped_release release;
            const auto limit = limit_threads(config_.threads);
            const auto surface = bake_level_set(sdf, bake);
            mesh = mesh_level_set(*surface, config_.mesh);
        }
        check_signals();
        return mesh_to_arrays(mesh);
    }

    py::object extract_mesh(const py::object& voxel_size_m, const py::object& colors_from) const {
        const BakeConfig bake = bake_config(voxel_size_m);
        const NeuralSdf& sdf = require_sdf("extract_mesh()");
        std::optional<fs::path> source;
        if (!colors_from.is_none())
            source = file_in_folder(path_string(colors_from), "surface.vdb");
        TriangleMesh mesh;
        {
            py::gil_scoped_release release;
            const auto limit = limit_threads(config_.threads);
            // The grids first: a wrong file is reported before the bake, not after it.
            SurfaceGrids grids;
            if (source) {
                grids = read_surface_grids(*source);
                if (grids.empty()) {
                    throw DataError("extract_mesh(colors_from='" + source->string() +
                                    "'): the file holds no 'color' or 'intensity' grid; `shine "
                                    "map` adds them to surface.vdb when the sequence folder has "
                                    "camera images or the scans carry intensity");
                }
            }
            const auto surface = bake_level_set(sdf, bake);
            mesh = mesh_level_set(*surface, config_.mesh);
            sample_surface_grids(grids, mesh);
        }
        check_signals();
        return mesh_to_python(mesh);
    }

    py::dict bake(const py::object& path, const py::object& voxel_size_m) const {
        const std::string file = path_string(path);
        const BakeConfig bake = bake_config(voxel_size_m);
        const NeuralSdf& sdf = require_sdf("bake()");
        BakeStats stats;
        std::size_t mem_bytes = 0;
        {
            py::gil_scoped_release release;
            const auto limit = limit_threads(config_.threads);
            const auto surface = bake_level_set(sdf, bake, &stats);
            write_level_set(file, surface);
            mem_bytes = surface->memUsage();
        }
        check_signals();
        py::dict out;
        out["voxel_size_m"] = stats.voxel_size_m;
        out["active_voxels"] = stats.active_voxels;
        out["mem_bytes"] = mem_bytes;
        out["file_bytes"] = file_bytes(file);
        return out;
    }

    void save(const py::object& path) const {
        const std::string file = path_string(path);
        const NeuralSdf& sdf = require_sdf("save()");
        py::gil_scoped_release release;
        save_neural_map(file, sdf, config_to_yaml(products_config()));
    }

    py::dict write_products(const py::object& out_dir) const {
        const std::string dir = path_string(out_dir);
        const NeuralSdf& sdf = require_sdf("write_products()");
        MapProducts products;
        {
            py::gil_scoped_release release;
            const auto limit = limit_threads(config_.threads);
            ensure_directory(dir);
            products = write_map_products(sdf, products_config(), dir);
        }
        check_signals();
        py::dict out;
        out["map"] = (fs::path(dir) / "map.vdb").string();
        out["surface"] = (fs::path(dir) / "surface.vdb").string();
        out["mesh"] = (fs::path(dir) / "mesh.ply").string();
        out["triangles"] = products.mesh.triangles;
        out["surface_mem_bytes"] = products.surface_mem_bytes;
        return out;
    }

    std::size_t memory_bytes() const {
        const NeuralSdf* sdf = current_sdf();
        return sdf ? sdf->memory_bytes() : 0;
    }

    py::dict stats() const {
        py::dict out;
        out["mode"] = mode_name(mode_);
        out["threads"] = config_.threads;
        out["leaf_size_m"] = config_.octree.leaf_size_m;
        const MappingStats* stats = batch_         ? &batch_->stats()
                                    : incremental_ ? &incremental_->stats()
                                                   : nullptr;
        if (stats) {
            out["frames"] = stats->frames;
            out["rays"] = stats->rays;
            out["iterations"] = stats->iterations;
            py::dict pre;
            pre["input_points"] = stats->preprocess.input;
            pre["dropped_nonfinite"] = stats->preprocess.dropped_nonfinite;
            pre["dropped_zero_range"] = stats->preprocess.dropped_zero_range;
            pre["dropped_range"] = stats->preprocess.dropped_range;
            pre["dropped_box"] = stats->preprocess.dropped_box;
            pre["dropped_downsample"] = stats->preprocess.dropped_downsample;
            pre["output_points"] = stats->preprocess.output;
            out["preprocess"] = pre;
            py::dict seconds;
            seconds["load"] = stats->load_seconds;
            seconds["allocate"] = stats->allocate_seconds;
            seconds["normals"] = stats->normals_seconds;
            seconds["train"] = stats->train_seconds;
            out["seconds"] = seconds;
            const double per_frame = stats->load_seconds + stats->allocate_seconds +
                                     stats->normals_seconds + stats->train_seconds;
            out["seconds_per_frame"] =
                stats->frames ? per_frame / static_cast<double>(stats->frames) : 0.0;
            py::dict loss;
            loss["bce"] = stats->final_bce;
            loss["eikonal"] = stats->final_eikonal;
            out["loss"] = loss;
        }
        if (batch_) {
            out["iterations_planned"] = batch_->planned_iterations();
        }
        if (incremental_) {
            py::dict inc;
            inc["median_seconds_per_frame"] = incremental_->median_frame_seconds();
            inc["state_bytes"] = incremental_->state_bytes();
            inc["iterations_per_frame"] = config_.incremental.iterations_per_frame;
            inc["consolidation"] = consolidation_dict();
            out["incremental"] = inc;
        }
        if (const NeuralSdf* sdf = current_sdf()) {
            py::dict map;
            map["corners"] = sdf->octree.num_corners();
            map["feature_precision"] = to_string(sdf->octree.feature_precision());
            map["feature_bytes"] = sdf->octree.feature_bytes();
            map["structure_bytes"] = sdf->octree.structure_bytes();
            map["decoder_bytes"] = sdf->decoder.num_params() * sizeof(float);
            map["map_bytes"] = sdf->memory_bytes();
            out["map"] = map;
            out["origin_world_m"] =
                std::vector<double>(sdf->origin_world_m.data(), sdf->origin_world_m.data() + 3);
        }
        rusage usage{};
        getrusage(RUSAGE_SELF, &usage);
        out["peak_rss_bytes"] = static_cast<std::size_t>(usage.ru_maxrss) * 1024;  // this process
        return out;
    }

    std::string config_yaml() const { return config_to_yaml(products_config()); }
    std::string mode() const { return mode_name(mode_); }
    std::size_t num_scans() const { return scans_; }
    int iterations_done() const { return batch_ ? batch_->iterations_done() : 0; }
    int iterations_planned() const {
        return batch_ ? batch_->planned_iterations() : config_.batch_iterations();
    }

  private:
    NeuralMap() = default;

    Scan make_scan(const py::handle& points, const py::handle& pose, const char* points_name,
                   const char* pose_name) const {
        Scan scan;
        scan.points_sensor = points3f(points, points_name);
        scan.T_world_sensor = pose_from_array(pose, pose_name);
        scan.source = "scan " + std::to_string(scans_) + " (Python)";
        return scan;
    }

    void require_mode(Mode wanted, const char* what) const {
        if (mode_ == Mode::kEmpty || mode_ == wanted) return;
        if (mode_ == Mode::kLoaded) {
            throw std::runtime_error(std::string(what) +
                                     ": a map read by NeuralMap.load() cannot be trained further "
                                     "(map.vdb holds no optimiser state); build a new NeuralMap");
        }
        throw std::runtime_error(std::string(what) + " needs a " + mode_name(wanted) +
                                 "-mode map, but this one is in " + mode_name(mode_) +
                                 " mode: use either integrate() (incremental) or add_scan() + "
                                 "train() (batch) on one map");
    }

    /// The configuration the products are made with: a batch map's is its mapper's (with the
    /// batch bake default, as `shine map` writes it).
    const MapperConfig& products_config() const { return batch_ ? batch_->config() : config_; }

    const NeuralSdf* current_sdf() const {
        if (batch_) return &batch_->sdf();
        if (incremental_) return &incremental_->sdf();
        return loaded_.get();
    }

    const NeuralSdf& require_sdf(const char* what) const {
        const NeuralSdf* sdf = current_sdf();
        if (!sdf) {
            throw std::runtime_error(std::string(what) +
                                     ": the map is empty; add scans with integrate() or "
                                     "add_scan() + train() first");
        }
        return *sdf;
    }

    BakeConfig bake_config(const py::object& voxel_size_m) const {
        BakeConfig bake = config_.bake;
        if (!voxel_size_m.is_none()) {
            const double v = voxel_size_m.cast<double>();
            if (!(v > 0.0) || !std::isfinite(v)) {
                throw py::value_error(
                    "voxel_size_m must be a positive number of metres or None "
                    "(half the leaf size), got " +
                    std::to_string(v));
            }
            bake.voxel_size_m = v;
        }
        return bake;
    }

    void warn_times_unused() {
        if (warned_times_) return;
        warned_times_ = true;
        PyErr_WarnEx(PyExc_UserWarning,
                     "NeuralMap.integrate(): per-point times are checked but not used yet "
                     "(the mapper does not deskew scans)",
                     1);
    }

    MapperConfig config_;
    Mode mode_ = Mode::kEmpty;
    std::unique_ptr<BatchMapper> batch_;
    std::unique_ptr<IncrementalMapper> incremental_;
    std::unique_ptr<NeuralSdf> loaded_;
    std::size_t scans_ = 0;
    bool warned_times_ = false;
    /// localize()'s track, and the map state it was made for.
    std::unique_ptr<MapLocalizer> localizer_;
    const NeuralSdf* localizer_sdf_ = nullptr;
    std::size_t localizer_scans_ = 0;
    int localizer_iterations_ = 0;
};

}  // namespace

void bind_neural_map(py::module_& m) {
    py::class_<NeuralMap>(m, "NeuralMap", R"doc(
A SHINE-Mapping neural SDF map: sparse multi-level feature grids in OpenVDB and a small MLP.

Build it in one of the two modes of ``shine map``:

* batch: ``add_scan(points, pose)`` for every scan, then ``train()``; gives the CLI's map bit
  for bit for the same scans, configuration, seed and thread count;
* incremental: ``integrate(points, pose)`` per scan, each trained at once (pretrained, frozen
  decoder), then ``consolidate()``; gives ``shine map --mode incremental``'s map bit for bit.

Points are sensor-frame (N, 3) float32/float64 arrays, poses 4x4 (or 3x4) T_world_sensor.
)doc")
        .def(py::init<const py::object&, const py::object&, const py::object&>(),
             py::arg("leaf_size_m") = py::none(), py::arg("config") = py::none(),
             py::arg("threads") = py::none(), R"doc(
Args:
    leaf_size_m: level-0 cell size in metres; None keeps the configuration's (0.2 by default).
    config: None (the defaults of ``examples/config.yaml``), a dict with that file's structure
        (e.g. ``{"run": {"seed": 1}}``), or the path of such a YAML file. Unknown keys and
        out-of-range values raise ValueError naming the key.
    threads: worker threads, 0 = all cores; None keeps the configuration's (0).
)doc")
        .def_static("load", &NeuralMap::load, py::arg("path"),
                    "Reads a map written by save() or `shine map` (map.vdb). It answers sdf(), "
                    "meshes and bakes, but cannot be trained further.")
        .def("integrate", &NeuralMap::integrate, py::arg("points"), py::arg("pose"),
             py::arg("times") = py::none(), R"doc(
Incremental mode: preprocesses one scan, grows the map around it and trains on it at once.

Args:
    points: (N, 3) float32/float64 points in the sensor frame.
    pose: (4, 4) or (3, 4) T_world_sensor.
    times: optional (N,) per-point times; checked, not used yet (no deskewing).
)doc")
        .def("consolidate", &NeuralMap::consolidate, py::arg("steps") = py::none(),
             py::arg("progress") = true, R"doc(
Incremental mode, when the scans are in: trains the kept scans (the last
``incremental.replay_frames``) together before the map is baked or saved, as ``shine map --mode
incremental`` does at the end of a sequence. It settles what each scan's few steps left behind
(on the real walk 84.9 -> 88.5 % of held-out rays within 10 cm) and, with
``refine.in_consolidation`` (on; ``{"refine": {"in_consolidation": False}}`` turns it off),
refines the kept scans' poses with the map (88.5 -> 90.3 %). integrate() may follow (the kept
scans stay where they were refined).

Args:
    steps: None: the configuration's ``incremental.consolidation_steps`` (1000).
    progress: print a progress line on stderr.
Returns:
    A dict: steps, scans, rays, surface_band_m, seconds, bce (the last step's);
    pose_corrections, a (K, 4, 4) array for the last K integrated scans (oldest first; K = 0
    without refinement): each scan's refined pose is ``pose_corrections[k] @ pose``; refinement,
    a list of the rounds (step, accepted, rejected, median_translation_m, median_rotation_deg,
    seconds).
)doc")
        .def("add_scan", &NeuralMap::add_scan, py::arg("points"), py::arg("pose"),
             "Batch mode: preprocesses a scan and grows the map around it; train() learns from "
             "all scans added.")
        .def("train", &NeuralMap::train, py::arg("steps") = py::none(), py::arg("progress") = true,
             R"doc(
Batch mode: runs the optimisation steps of the schedule not yet done (250 at 0.2 m by default).

Args:
    steps: run at most this many more steps (None: all remaining); stopping early and calling
        train() again gives the same map as one uninterrupted call.
    progress: print a progress line on stderr.
Returns:
    True once every step of the schedule has run.
Ctrl-C stops after the current step and raises KeyboardInterrupt; train() may then be called
again to continue.
)doc")
        .def("sdf", &NeuralMap::sdf_values, py::arg("points"), R"doc(
Signed distance and its gradient at world-frame points.

Returns:
    (values (N,) float32 metres, positive in free space; gradients (N, 3) float32), NaN where no
    level of the map covers the point.
)doc")
        .def("localize", &NeuralMap::localize, py::arg("points"),
             py::arg("initial_pose") = py::none(), R"doc(
Localises a scan in this map without changing it (``shine localize``, docs/localize.md).

Successive calls track: each scan starts from the constant-velocity prediction of the poses
before it; a failed scan is recovered by ICP against the map's surface and headings, then by a
search around the prediction. ``initial_pose`` starts a new track there; the first call without
one searches around the world origin.
Args:
    points: (N, 3) sensor-frame points.
    initial_pose: a 4x4 (or 3x4) T_world_sensor to start from, or None.
Returns:
    (pose (4, 4) float64 T_world_sensor, info dict: localized, source, points, valid_points,
    inlier_ratio, residual_m, condition_number, status, iterations, candidates, seconds). A scan
    that is not localised returns the prediction with localized False.
)doc")
        .def("extract_triangle_mesh", &NeuralMap::extract_triangle_mesh,
             py::arg("voxel_size_m") = py::none(), R"doc(
Bakes the map into a level set and meshes its zero crossing (OpenVDB volumeToMesh).

Args:
    voxel_size_m: bake resolution; None: the configuration's (half the leaf size).
Returns:
    (vertices (V, 3) float64 world frame, triangles (T, 3) int32), without colours: see
    extract_mesh().
)doc")
        .def("extract_mesh", &NeuralMap::extract_mesh, py::arg("voxel_size_m") = py::none(),
             py::arg("colors_from") = py::none(), R"doc(
extract_triangle_mesh() as a shinevdb.Mesh, with colours and reflectance taken from a surface.

A neural map holds geometry only: ``shine map`` fuses colour (camera images) and reflectance
(scan intensity) after training and bakes them beside the level set, into surface.vdb's "color"
and "intensity" grids, never into map.vdb. So ``colors`` and ``intensity`` are None unless
``colors_from`` names such a surface.

Args:
    voxel_size_m: bake resolution; None: the configuration's (half the leaf size).
    colors_from: None, or a surface.vdb with a "color" and/or "intensity" grid, or the ``shine
        map`` output folder holding it (e.g. the folder whose map.vdb NeuralMap.load() read).
        Its grids are sampled at this mesh's vertices in the world frame, by extract_mesh()'s
        rule (the nearest active voxel around each vertex; (0, 0, 0) / NaN where none is).
Returns:
    A Mesh: vertices (V, 3) float64 world frame, triangles (T, 3) int32, colors (V, 3) uint8 or
    None, intensity (V,) float32 or None.
Raises:
    ValueError when ``colors_from`` holds neither grid; OSError naming it when it is missing
    or not a .vdb.
)doc")
        .def("bake", &NeuralMap::bake, py::arg("path"), py::arg("voxel_size_m") = py::none(),
             "Writes the surface level set (OpenVDB FloatGrid 'surface', class LEVEL_SET) to "
             "`path`, like surface.vdb of `shine map`; returns its statistics.")
        .def("save", &NeuralMap::save, py::arg("path"),
             "Writes the neural map (map.vdb format, configuration included) to `path`.")
        .def("write_products", &NeuralMap::write_products, py::arg("out_dir"),
             "Writes map.vdb, surface.vdb and mesh.ply into `out_dir` exactly as `shine map` "
             "does; returns their paths.")
        .def_property_readonly("memory_bytes", &NeuralMap::memory_bytes,
                               "Bytes of the map: features, OpenVDB structure and decoder.")
        .def_property_readonly("stats", &NeuralMap::stats,
                               "The run's figures as stats.json of `shine map` holds them "
                               "(frames, rays, seconds per stage, map bytes, loss).")
        .def_property_readonly(
            "config_yaml", &NeuralMap::config_yaml,
            "The effective configuration as YAML (examples/config.yaml form): after "
            "train(), the one the map is made with and save() stores.")
        .def_property_readonly("mode", &NeuralMap::mode,
                               "'empty', 'batch', 'incremental' or 'loaded'.")
        .def_property_readonly("num_scans", &NeuralMap::num_scans)
        .def_property_readonly("iterations_done", &NeuralMap::iterations_done)
        .def_property_readonly("iterations_planned", &NeuralMap::iterations_planned,
                               "Steps of batch mode's schedule for this configuration.");
}

}  // namespace shinevdb
