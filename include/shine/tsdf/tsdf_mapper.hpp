// Scan sequence -> TSDF volume -> mesh: the VDBFusion baseline fed exactly like `shine map`.
//
// Each scan goes through the same preprocess_scan() as the neural mapper (range crop, 5 cm voxel
// downsampling, by default) and into the same map frame: the first scan's position rounded to
// whole kilometres (BatchMapper's convention), so both methods integrate the same points and
// their meshes are directly comparable. Scans are integrated one at a time, in the order given.
#pragma once

#include <cstddef>

#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/preprocess.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/tsdf/tsdf_mesh.hpp"
#include "shine/tsdf/tsdf_volume.hpp"

namespace shine {

/// All settings of a TSDF run; the preprocessing defaults are `shine map`'s.
struct TsdfMapperConfig {
    PreprocessConfig preprocess;
    TsdfConfig tsdf;
    TsdfMeshConfig mesh;

    /// Throws ConfigError naming the option if a value is out of range.
    void validate() const;
};

/// Counts and wall-clock seconds of a TSDF run, for stats.json.
struct TsdfMappingStats {
    std::size_t frames = 0;
    std::size_t points = 0;         ///< points integrated (after preprocessing)
    std::size_t voxel_updates = 0;  ///< TSDF updates (one per point and voxel with sdf > -trunc)
    PreprocessStats preprocess;
    double preprocess_seconds = 0.0;  ///< preprocessing and the move to the map frame
    double integrate_seconds = 0.0;
};

/// Integrates scans into a TSDF volume and meshes it.
class TsdfMapper {
  public:
    /// Throws ConfigError if `config` is out of range.
    explicit TsdfMapper(const TsdfMapperConfig& config);

    /// Preprocesses a scan, moves it to the map frame and integrates it. The first scan fixes the
    /// map origin (its position rounded to whole kilometres). Throws DataError for invalid points
    /// (with the default InvalidPointPolicy) naming scan.source.
    void add_scan(const Scan& scan);

    /// The mesh of the current volume with config().mesh, in the world frame.
    TriangleMesh extract_mesh() const;

    const TsdfVolume& volume() const { return volume_; }
    const TsdfMappingStats& stats() const { return stats_; }
    const TsdfMapperConfig& config() const { return config_; }

  private:
    TsdfMapperConfig config_;
    TsdfVolume volume_;
    TsdfMappingStats stats_;
    bool origin_set_ = false;
};

}  // namespace shine
