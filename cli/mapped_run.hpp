// How a `shine map` run placed and deskewed the scans it scored, read back from its output
// folder, so that `shine eval --heldout DATA --run OUT` scores the run's mesh as the run itself
// did (stats.json "heldout"):
//
// - poses: with pose refinement the run mapped at its refined poses and placed each held-out
//   scan with the corrections of the mapped scans around it, both written to
//   OUT/poses_refined.txt (one pose per scan of the sequence); scored at the sequence's own
//   poses instead, the map's refined frame counts against it (on the real walk 90.67 -> 88.05 %
//   of held-out rays within 10 cm). Without refinement the sequence's poses are the run's.
// - deskew: where the run deskewed (stats.json "deskew" active), the held-out scans are deskewed
//   with the same poses, and scans without a time field are timed from their azimuth by the
//   run's sweep model (stats.json "deskew" "sweep"). On the real KITTI-360 drive, not deskewed,
//   the held-out rays within 10 cm drop from 76.70 to 66.13 %.
#pragma once

#include <Eigen/Geometry>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "shine/io/scan_sequence.hpp"
#include "shine/io/sweep_times.hpp"
#include "shine/mapper/sequence_deskew.hpp"

namespace shine::cli {

/// What scoring held-out scans as a run did takes from its output folder.
struct MappedRun {
    /// The poses the run scored each scan of the sequence at (OUT/poses_refined.txt), or empty:
    /// the sequence's own.
    std::vector<Eigen::Isometry3d> poses_world_sensor;
    /// The run deskewed its scans: deskew the held-out ones alike.
    std::optional<DeskewConfig> deskew;
    /// Scans without a time field were timed from their azimuth by this model.
    std::optional<SweepTimeModel> sweep;

    /// One line for the printout: where the poses come from, whether and how scans are deskewed.
    std::string describe() const;
    /// `sequence` with the run's poses and sweep model.
    ScanSequence apply(const ScanSequence& sequence) const;
};

/// Reads run_dir/stats.json and, when present, run_dir/poses_refined.txt and poses_given.txt.
/// Throws IoError naming the file when stats.json is missing; DataError naming it when it is not
/// a JSON object or its deskew record is damaged (io/run_deskew_record.hpp), when the pose files
/// do not pair with `sequence` (another count of scans, or a run that was given other poses than
/// the sequence's: it mapped another sequence), or when the run deskewed by the azimuth but its
/// stats.json predates the recorded sweep model; ConfigError for a run that estimated its poses
/// (it scored its held-out scans itself).
MappedRun read_mapped_run(const std::filesystem::path& run_dir, const ScanSequence& sequence);

}  // namespace shine::cli
