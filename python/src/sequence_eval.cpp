// shinevdb.read_sequence (the CLI's scan readers) and shinevdb.evaluate (`shine eval`).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <optional>
#include <string>

#include "long_call.hpp"
#include "numpy_io.hpp"
#include "shine/eval/mesh_metrics.hpp"
#include "shine/eval/tiled_evaluation.hpp"
#include "shine/io/scan_sequence.hpp"

namespace shinevdb {
namespace {
using namespace shine;

/// Iterator over a ScanSequence: each step reads one scan from disk.
class SequenceReader {
  public:
    SequenceReader(const std::string& path, const ScanSequenceOptions& options)
        : sequence_(ScanSequence::open(path, options)) {}

    py::tuple next() {
        if (index_ >= sequence_.size()) throw py::stop_iteration();
        std::optional<Scan> scan;
        {
            py::gil_scoped_release release;
            scan.emplace(sequence_.load(index_));
        }
        const Eigen::Isometry3d& pose = scan->T_world_sensor;
        ++index_;
        return py::make_tuple(take_points(std::move(scan->points_sensor)), pose_to_array(pose),
                              py::none());
    }

    std::size_t size() const { return sequence_.size(); }
    py::object pose(std::size_t i) const {
        if (i >= sequence_.size()) throw py::index_error("scan index out of range");
        return pose_to_array(sequence_.pose(i));
    }
    std::string scan_path(std::size_t i) const {
        if (i >= sequence_.size()) throw py::index_error("scan index out of range");
        return sequence_.scan_path(i).string();
    }

  private:
    ScanSequence sequence_;
    std::size_t index_ = 0;
};

std::string fspath(const py::handle& path) {
    return py::str(py::module_::import("os").attr("fspath")(path)).cast<std::string>();
}

}  // namespace

void bind_sequence_eval(py::module_& m) {
    py::class_<SequenceReader>(m, "ScanSequenceReader",
                               "Iterator of (points, pose, times) returned by read_sequence().")
        .def("__iter__", [](SequenceReader& self) -> SequenceReader& { return self; })
        .def("__next__", &SequenceReader::next)
        .def("__len__", &SequenceReader::size)
        .def("pose", &SequenceReader::pose, py::arg("index"),
             "T_world_sensor of scan `index` (4x4 float64), without reading the scan.")
        .def("scan_path", &SequenceReader::scan_path, py::arg("index"));

    m.def(
        "read_sequence",
        [](const py::object& path, int first_frame, int last_frame, int frame_step,
           const py::object& poses) {
            ScanSequenceOptions options;
            options.first_frame = first_frame;
            options.last_frame = last_frame;
            options.frame_step = frame_step;
            if (!poses.is_none()) options.poses_path = fspath(poses);
            return SequenceReader(fspath(path), options);
        },
        py::arg("path"), py::arg("first_frame") = 0, py::arg("last_frame") = -1,
        py::arg("frame_step") = 1, py::arg("poses") = py::none(), R"doc(
Reads a scan sequence the way `shine map` does: KITTI odometry (velodyne/*.bin, poses.txt,
optional calib.txt) or a folder of .ply / .pcd scans with KITTI or TUM poses.

Returns:
    An iterator (with len()) of (points (N, 3) float32 sensor frame, pose (4, 4) float64
    T_world_sensor, times) per scan, read lazily; times is None (the readers have no per-point
    times yet).
)doc");

    m.def(
        "evaluate",
        [](const py::handle& pred_mesh, const py::handle& ref_mesh, double threshold_m,
           const py::object& tile_m) {
            const TriangleMesh pred = mesh_from_python(pred_mesh, "pred_mesh");
            const TriangleMesh ref = mesh_from_python(ref_mesh, "ref_mesh");
            if (!(threshold_m > 0.0) || !std::isfinite(threshold_m)) {
                throw py::value_error("threshold_m must be a positive number of metres, got " +
                                      std::to_string(threshold_m));
            }
            EvalConfig config;
            config.threshold_m = threshold_m;
            TiledEvalConfig tiled;
            tiled.eval = config;
            if (!tile_m.is_none()) {
                tiled.tile_m = tile_m.cast<double>();
                if (!(tiled.tile_m > 0.0) || !std::isfinite(tiled.tile_m)) {
                    throw py::value_error("tile_m must be a positive number of metres, got " +
                                          std::to_string(tiled.tile_m));
                }
            }
            MeshMetrics r;
            TiledEvaluation t;
            {
                py::gil_scoped_release release;
                if (tile_m.is_none()) {
                    r = evaluate_meshes(pred, ref, config);
                } else {
                    t = evaluate_meshes_tiled(pred, ref, tiled);
                    r = t.metrics;
                }
            }
            check_signals();
            py::dict out;
            if (!tile_m.is_none()) {
                out["tiles_scored"] = t.tiles_scored;
                out["unscored_pred_area_m2"] = t.unscored_pred_area_m2;
            }
            out["accuracy_m"] = r.accuracy_m;
            out["completion_m"] = r.completion_m;
            out["chamfer_l1_m"] = r.chamfer_l1_m;
            out["precision"] = r.precision;
            out["completion_ratio"] = r.completion_ratio;
            out["fscore"] = r.fscore;
            out["threshold_m"] = r.threshold_m;
            out["sample_density_per_m2"] = r.sample_density_per_m2;
            out["pred_area_m2"] = r.pred_area_m2;
            out["ref_area_m2"] = r.ref_area_m2;
            out["ref_observed_area_m2"] = r.ref_observed_area_m2;
            out["pred_points"] = r.pred_points;
            out["accuracy_points"] = r.accuracy_points;
            out["ref_points"] = r.ref_points;
            out["ref_observed_points"] = r.ref_observed_points;
            return out;
        },
        py::arg("pred_mesh"), py::arg("ref_mesh"), py::arg("threshold_m") = 0.1,
        py::arg("tile_m") = py::none(), R"doc(
Scores a mesh against a reference as `shine eval` does (SHINE-Mapping's protocol).

Args:
    pred_mesh, ref_mesh: a PLY path, or (vertices, triangles) / (vertices, triangles,
        face_observed) arrays; completion counts only observed reference faces (all when the
        reference has no flags; the simulator's gt_mesh.ply marks them).
    threshold_m: precision / recall threshold.
    tile_m: score tile by tile (square columns of this edge, each at the protocol's density,
        combined by area), as `shine eval --tile-m` does: for a city-sized scene, which one
        sampling covers too sparsely for the threshold.
Returns:
    A dict: accuracy_m, completion_m, chamfer_l1_m, precision, completion_ratio, fscore (ratios in
    [0, 1]), and the sampling figures (with tile_m: the lowest tile's density, tiles_scored and
    unscored_pred_area_m2).
)doc");
}

}  // namespace shinevdb
