#include "shine/eval/tiled_evaluation.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/core/progress.hpp"
#include "shine/eval/mesh_sampling.hpp"
#include "shine/eval/region_crop.hpp"

namespace shine {
namespace tiled_evaluation_internal {

/// The square columns of the scene.
struct TileGrid {
    Eigen::Vector2d origin_m = Eigen::Vector2d::Zero();
    double tile_m = 1.0;
    long nx = 0, ny = 0;

    long clamp_x(double x_m) const {
        return std::clamp(static_cast<long>(std::floor((x_m - origin_m.x()) / tile_m)), 0L, nx - 1);
    }
    long clamp_y(double y_m) const {
        return std::clamp(static_cast<long>(std::floor((y_m - origin_m.y()) / tile_m)), 0L, ny - 1);
    }
    std::size_t index(long ix, long iy) const { return static_cast<std::size_t>(iy * nx + ix); }
};

}  // namespace tiled_evaluation_internal

using namespace tiled_evaluation_internal;

TiledEvaluation evaluate_meshes_tiled(const TriangleMesh& pred_mesh, const TriangleMesh& ref,
                                      const TiledEvalConfig& config, const MoverTracks* movers) {
    if (!(std::isfinite(config.tile_m) && config.tile_m > 0.0)) {
        throw ConfigError("tiled evaluation: tile_m = " + std::to_string(config.tile_m) +
                          " must be positive");
    }
    if (!(std::isfinite(config.margin_m) && config.margin_m > 0.0)) {
        throw ConfigError("tiled evaluation: margin_m = " + std::to_string(config.margin_m) +
                          " must be positive");
    }
    if (ref.triangles.size() > std::numeric_limits<std::uint32_t>::max() ||
        pred_mesh.triangles.size() > std::numeric_limits<std::uint32_t>::max()) {
        throw DataError("tiled evaluation: more than 2^32 triangles in a mesh");
    }
    const bool ref_flags = ref.face_observed.size() == ref.triangles.size();
    if (!ref_flags && !ref.face_observed.empty()) {
        throw DataError("tiled evaluation: the reference has " +
                        std::to_string(ref.face_observed.size()) + " observed flags for " +
                        std::to_string(ref.triangles.size()) + " triangles");
    }
    // Both meshes in the reference's frame, as evaluate_meshes scores them.
    const TriangleMesh pred = pred_mesh.origin_world_m == ref.origin_world_m
                                  ? TriangleMesh()
                                  : in_frame(pred_mesh, ref.origin_world_m);
    const TriangleMesh& p = pred_mesh.origin_world_m == ref.origin_world_m ? pred_mesh : pred;
    for (const TriangleMesh* mesh : {&p, &ref}) {
        for (const Eigen::Vector3i& t : mesh->triangles) {
            if (t.minCoeff() < 0 || t.maxCoeff() >= static_cast<int>(mesh->vertices.size())) {
                throw DataError("tiled evaluation: a triangle's vertex index is out of range");
            }
        }
    }

    // The grid covers every centroid of both meshes.
    Eigen::AlignedBox2d extent;
    for (const TriangleMesh* mesh : {&p, &ref}) {
        for (const Eigen::Vector3i& t : mesh->triangles) {
            const Eigen::Vector3f c = triangle_centroid(*mesh, t);
            if (c.allFinite()) extent.extend(c.head<2>().cast<double>());
        }
    }
    if (extent.isEmpty()) throw DataError("tiled evaluation: the reference is empty");
    TileGrid grid;
    grid.origin_m = extent.min();
    grid.tile_m = config.tile_m;
    const Eigen::Vector2d size_m = extent.sizes();
    const double nx = std::floor(size_m.x() / config.tile_m) + 1.0;
    const double ny = std::floor(size_m.y() / config.tile_m) + 1.0;
    if (nx * ny > 1e6) {
        throw ConfigError("tiled evaluation: tile_m = " + std::to_string(config.tile_m) +
                          " m makes more than 10^6 tiles of a " + std::to_string(size_m.x()) +
                          " x " + std::to_string(size_m.y()) + " m scene");
    }
    grid.nx = static_cast<long>(nx);
    grid.ny = static_cast<long>(ny);
    const std::size_t num_tiles = static_cast<std::size_t>(grid.nx * grid.ny);

    std::vector<std::vector<std::uint32_t>> pred_of(num_tiles), ref_of(num_tiles);
    for (std::size_t i = 0; i < p.triangles.size(); ++i) {
        const Eigen::Vector3f c = triangle_centroid(p, p.triangles[i]);
        if (!c.allFinite()) continue;
        pred_of[grid.index(grid.clamp_x(c.x()), grid.clamp_y(c.y()))].push_back(
            static_cast<std::uint32_t>(i));
    }
    std::vector<std::uint32_t> home_tile(ref.triangles.size(), 0);
    for (std::size_t i = 0; i < ref.triangles.size(); ++i) {
        const Eigen::Vector3f c = triangle_centroid(ref, ref.triangles[i]);
        if (!c.allFinite()) continue;
        home_tile[i] =
            static_cast<std::uint32_t>(grid.index(grid.clamp_x(c.x()), grid.clamp_y(c.y())));
        for (long iy = grid.clamp_y(c.y() - config.margin_m);
             iy <= grid.clamp_y(c.y() + config.margin_m); ++iy) {
            for (long ix = grid.clamp_x(c.x() - config.margin_m);
                 ix <= grid.clamp_x(c.x() + config.margin_m); ++ix) {
                ref_of[grid.index(ix, iy)].push_back(static_cast<std::uint32_t>(i));
            }
        }
    }

    TiledEvaluation result;
    MeshMetrics& m = result.metrics;
    m.threshold_m = config.eval.threshold_m;
    m.sample_density_per_m2 = std::numeric_limits<double>::infinity();
    GhostMetrics& g = result.ghost;
    g.sample_density_per_m2 = std::numeric_limits<double>::infinity();
    double precision_sum = 0.0, accuracy_sum = 0.0, accuracy_weight = 0.0;
    double recall_sum = 0.0, completion_sum = 0.0;
    m.ref_area_m2 = mesh_surface_area_m2(ref);

    std::vector<int> pred_slot(p.vertices.size(), -1), ref_slot(ref.vertices.size(), -1);
    Progress progress("eval tiles", num_tiles, config.show_progress);
    for (std::size_t tile = 0; tile < num_tiles; ++tile) {
        progress.update(tile, std::to_string(result.tiles_scored) + " scored");
        if (pred_of[tile].empty() && ref_of[tile].empty()) continue;
        // The reference around the tile, observed only inside it.
        TriangleMesh ref_tile = extract_triangles(ref, ref_of[tile], ref_slot);
        ref_tile.face_observed.resize(ref_tile.triangles.size(), 1);
        bool observed = false;
        for (std::size_t j = 0; j < ref_of[tile].size(); ++j) {
            std::uint8_t& o = ref_tile.face_observed[j];
            o = home_tile[ref_of[tile][j]] == tile && o != 0;
            observed = observed || o != 0;
        }
        TriangleMesh pred_tile = extract_triangles(p, pred_of[tile], pred_slot);
        pred_tile.face_observed.clear();
        if (!observed) {
            result.unscored_pred_area_m2 += mesh_surface_area_m2(pred_tile);
            continue;
        }
        const MeshMetrics t = evaluate_meshes(pred_tile, ref_tile, config.eval);
        ++result.tiles_scored;
        precision_sum += t.precision * t.pred_area_m2;
        if (t.pred_points > 0) {
            const double w = t.pred_area_m2 * static_cast<double>(t.accuracy_points) /
                             static_cast<double>(t.pred_points);
            accuracy_sum += t.accuracy_m * w;
            accuracy_weight += w;
        }
        recall_sum += t.completion_ratio * t.ref_observed_area_m2;
        completion_sum += t.completion_m * t.ref_observed_area_m2;
        m.pred_area_m2 += t.pred_area_m2;
        m.ref_observed_area_m2 += t.ref_observed_area_m2;
        m.pred_points += t.pred_points;
        m.accuracy_points += t.accuracy_points;
        m.ref_points += t.ref_points;
        m.ref_observed_points += t.ref_observed_points;
        m.sample_density_per_m2 = std::min(m.sample_density_per_m2, t.sample_density_per_m2);
        if (movers) {
            GhostConfig ghost_config;
            ghost_config.eval = config.eval;
            const GhostMetrics tg = measure_ghost_area(pred_tile, ref_tile, *movers, ghost_config);
            g.ghost_area_m2 += tg.ghost_area_m2;
            g.off_static_area_m2 += tg.off_static_area_m2;
            g.pred_area_m2 += tg.pred_area_m2;
            g.ref_observed_area_m2 += tg.ref_observed_area_m2;
            g.pred_samples += tg.pred_samples;
            g.ghost_samples += tg.ghost_samples;
            g.threshold_m = tg.threshold_m;
            g.swept_margin_m = tg.swept_margin_m;
            g.num_movers = tg.num_movers;
            g.sample_density_per_m2 = std::min(g.sample_density_per_m2, tg.sample_density_per_m2);
        }
    }
    progress.finish(std::to_string(result.tiles_scored) + " tiles scored");
    if (result.tiles_scored == 0) {
        throw DataError("tiled evaluation: the reference has no observed surface");
    }
    m.precision = m.pred_area_m2 > 0.0 ? precision_sum / m.pred_area_m2 : 0.0;
    m.accuracy_m =
        accuracy_weight > 0.0 ? accuracy_sum / accuracy_weight : config.eval.accuracy_max_m;
    m.completion_ratio = recall_sum / m.ref_observed_area_m2;
    m.completion_m = completion_sum / m.ref_observed_area_m2;
    m.chamfer_l1_m = 0.5 * (m.accuracy_m + m.completion_m);
    const double pr = m.precision + m.completion_ratio;
    m.fscore = pr > 0.0 ? 2.0 * m.precision * m.completion_ratio / pr : 0.0;
    if (movers) {
        g.ghost_share =
            g.ref_observed_area_m2 > 0.0 ? g.ghost_area_m2 / g.ref_observed_area_m2 : 0.0;
    } else {
        g.sample_density_per_m2 = 0.0;
    }
    return result;
}

}  // namespace shine
