// Wall-clock seconds of a mapping run, stage by stage (`shine map --profile`, stats.json
// "profile"): where the time of a frame goes, so that speed work starts from a measurement.
//
// Stages, in pipeline order:
//   load        reading a scan from disk (ScanSequence::load)
//   preprocess  range crop, voxel downsample, transform into the map frame
//   allocate    growing the octree around the scan's points (and the optimiser state)
//   normals     surface normals at the endpoints (surface_normals.hpp)
//   sample      drawing the training samples along the rays (ray_sampler.hpp)
//   train       everything else of the optimisation steps: corner lookups, decoder, loss,
//               gradient reduction, Adam
//   importance  incremental mode's importance pass (paper Eq. (4))
//   bake        baking the level set (and writing surface.vdb)
//   mesh        meshing it (and writing mesh.ply)
// Per-frame stages are kept per frame (incremental mode: all but bake and mesh; batch mode:
// load, preprocess, allocate); the others are run totals.
#pragma once

#include <array>
#include <cstddef>
#include <string>
#include <vector>

namespace shine {

enum class Stage : int {
    kLoad = 0,
    kPreprocess,
    kAllocate,
    kNormals,
    kSample,
    kTrain,
    kImportance,
    kBake,
    kMesh,
};
constexpr int kNumStages = 9;

/// Lower-case name of a stage ("load", "preprocess", ...), as in stats.json.
const char* stage_name(Stage stage);

/// Seconds per stage.
struct StageSeconds {
    std::array<double, kNumStages> seconds{};

    double& operator[](Stage s) { return seconds[static_cast<std::size_t>(s)]; }
    double operator[](Stage s) const { return seconds[static_cast<std::size_t>(s)]; }
    double sum() const;
    StageSeconds& operator+=(const StageSeconds& other);
};

/// Per-frame and once-per-run stage times of one mapping run.
struct StageProfile {
    int threads = 1;                   ///< TBB's allowed parallelism during the run
    std::vector<StageSeconds> frames;  ///< per-frame stages (zero where a stage ran once)
    StageSeconds run;                  ///< stages that ran once for the whole run

    /// Per stage, the median over frames of that stage's seconds (0 without frames).
    StageSeconds frame_medians() const;
    /// Median over frames of the frames' summed stage seconds (0 without frames).
    double median_frame_seconds() const;
    /// Per stage, the frames' sum plus the once-per-run seconds.
    StageSeconds totals() const;
    /// A plain-text table: per stage the per-frame median, the run total and its share.
    std::string format_table() const;
};

}  // namespace shine
