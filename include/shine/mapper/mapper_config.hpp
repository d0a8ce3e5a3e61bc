// All settings of a mapping run in one struct with the paper's defaults (see DESIGN.md), and
// their YAML form. Parsing rejects unknown keys and out-of-range values, naming the key.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "shine/bake/level_set_bake.hpp"
#include "shine/io/preprocess.hpp"
#include "shine/map/feature_octree.hpp"
#include "shine/mapper/incremental_config.hpp"
#include "shine/mapper/trainer.hpp"
#include "shine/mesh/level_set_mesh.hpp"
#include "shine/model/decoder.hpp"
#include "shine/sampling/ray_sampler.hpp"
#include "shine/sampling/surface_normals.hpp"

namespace shine {

/// PreprocessConfig's defaults with the mapper's voxel size (MapperConfig::preprocess).
PreprocessConfig mapper_preprocess_defaults();

struct MapperConfig {
    /// The scans' preprocessing, with one point kept per 0.2 m voxel (PreprocessConfig's own
    /// default, which the TSDF baseline keeps, is 0.05 m): a 0.05 m grid keeps most points near
    /// the sensor, so most training samples would land on the few metres around it. Measured on
    /// the street (docs/performance.md): higher F-scores in both modes at 0.2 m and 0.1 m leaves,
    /// with a quarter of the rays to sample, find normals for and allocate.
    PreprocessConfig preprocess = mapper_preprocess_defaults();
    FeatureOctreeConfig octree;
    DecoderConfig decoder;
    SamplingConfig sampling;
    NormalConfig normals;  ///< endpoint normals for labels that are true distances
    TrainerConfig trainer;
    /// Batch-mode optimisation steps; -1 (the default) = auto, batch_iterations().
    int iterations = -1;
    /// lr decays to this fraction (cosine) by the end (batch: of the run; incremental: of each
    /// scan's steps)
    float final_learning_rate_ratio = 0.1f;
    IncrementalConfig incremental;  ///< `shine map --mode incremental`
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

    /// Steps batch mode runs: `iterations`, or for auto 2400 at the default 0.2 m leaf and
    /// 2400 * (0.2 m / leaf_size_m)^1.5 for finer leaves (a surface map has ~4x the features per
    /// halving of the leaf; 6788 at 0.1 m), at most 50,000. With scans thinned to 0.2 m and two
    /// surface samples and one free-space sample per ray, 2400 steps score higher on the street
    /// than 6000 did on scans thinned to 0.05 m (docs/performance.md).
    int batch_iterations() const;

    /// Copies feature_dim/seed into the sub-configs that repeat them, and checks ranges.
    void finalize();
};

/// Reads `path` (YAML) over the defaults in `config`. Throws ConfigError naming the file and key.
void load_config_yaml(const std::filesystem::path& path, MapperConfig& config);

/// The configuration as YAML (stored in map.vdb and accepted by load_config_yaml).
std::string config_to_yaml(const MapperConfig& config);

/// Parses YAML text (as produced by config_to_yaml) over `config`; `source` names it in errors.
void parse_config_yaml(const std::string& text, const std::string& source, MapperConfig& config);

}  // namespace shine
