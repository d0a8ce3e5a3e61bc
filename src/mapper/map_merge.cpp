#include "shine/mapper/map_merge.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <set>
#include <sstream>

#include "shine/core/error.hpp"
#include "shine/map/feature_octree_impl.hpp"
#include "shine/model/map_file.hpp"

namespace shine {
namespace {

namespace fs = std::filesystem;

std::string core_text(const TileCore& c) {
    std::ostringstream s;
    s << "[" << c.x_min_m << ", " << c.x_max_m << ") x [" << c.y_min_m << ", " << c.y_max_m << ")";
    return s.str();
}

/// Parses one bound: a number, "inf" or "-inf" (strtod's spellings). NaN is rejected by the
/// caller's min < max check.
bool parse_bound(const std::string& text, double& out) {
    if (text.empty()) return false;
    char* end = nullptr;
    errno = 0;
    out = std::strtod(text.c_str(), &end);
    return end == text.c_str() + text.size() && errno != ERANGE;
}

void check_core(const TileCore& c, const std::string& where) {
    if (!(c.x_min_m < c.x_max_m) || !(c.y_min_m < c.y_max_m)) {
        throw ConfigError(where + ": the core box " + core_text(c) +
                          " is empty or not a number; give xmin,ymin,xmax,ymax with xmin < xmax "
                          "and ymin < ymax (world metres)");
    }
}

/// Feature rows of one tile level's corners, visited in tree order: f(corner, row).
template <typename F>
void for_each_corner(const LevelIndex& level, F&& f) {
    for (auto leaf = level.grid->tree().cbeginLeaf(); leaf; ++leaf) {
        std::size_t slot = level.leaves[leaf->transientData()].first_slot;
        for (auto voxel = leaf->cbeginValueOn(); voxel; ++voxel) {
            f(voxel.getCoord() - level.shift, level.rows[slot++]);
        }
    }
}

std::string dims_text(const std::vector<int>& dims) {
    std::string s;
    for (int d : dims) s += (s.empty() ? "" : ",") + std::to_string(d);
    return "[" + s + "]";
}

/// Throws DataError naming `path` when `tile` cannot be merged with `first` (loaded from
/// `first_path`).
void check_compatible(const NeuralSdf& first, const fs::path& first_path, const NeuralSdf& tile,
                      const fs::path& path) {
    const auto mismatch = [&](const std::string& what, const std::string& mine,
                              const std::string& theirs) {
        throw DataError("cannot merge '" + path.string() + "' with '" + first_path.string() +
                        "': " + what + " differs (" + mine + " vs " + theirs +
                        "); every tile must be mapped with the same settings (map.origin_world_m, "
                        "map.leaf_size_m, map.num_levels, map.feature_dim, map.feature_precision) "
                        "and the same frozen decoder (--mode incremental, "
                        "incremental.decoder_weights)");
    };
    // Two different numbers in the fewest digits that tell them apart.
    const auto two_numbers = [](const std::vector<double>& a, const std::vector<double>& b) {
        std::pair<std::string, std::string> text;
        for (int digits = 6; digits <= 17; ++digits) {
            const auto format = [digits](const std::vector<double>& v) {
                std::ostringstream s;
                s.precision(digits);
                for (std::size_t i = 0; i < v.size(); ++i) s << (i ? ", " : "") << v[i];
                return v.size() > 1 ? "[" + s.str() + "]" : s.str();
            };
            text = {format(a), format(b)};
            if (text.first != text.second) break;
        }
        return text;
    };
    const FeatureOctreeConfig& a = tile.octree.config();
    const FeatureOctreeConfig& b = first.octree.config();
    if (tile.origin_world_m != first.origin_world_m) {
        const auto& o = tile.origin_world_m;
        const auto& p = first.origin_world_m;
        const auto [mine, theirs] = two_numbers({o.x(), o.y(), o.z()}, {p.x(), p.y(), p.z()});
        mismatch("the map origin (origin_world_m)", mine, theirs);
    }
    if (a.leaf_size_m != b.leaf_size_m) {
        const auto [mine, theirs] = two_numbers({a.leaf_size_m}, {b.leaf_size_m});
        mismatch("the leaf size", mine, theirs);
    }
    if (a.num_levels != b.num_levels) {
        mismatch("the number of levels", std::to_string(a.num_levels),
                 std::to_string(b.num_levels));
    }
    if (a.feature_dim != b.feature_dim) {
        mismatch("the feature dimension", std::to_string(a.feature_dim),
                 std::to_string(b.feature_dim));
    }
    if (tile.octree.feature_precision() != first.octree.feature_precision()) {
        mismatch("the feature precision", to_string(tile.octree.feature_precision()),
                 to_string(first.octree.feature_precision()));
    }
    if (tile.decoder.config().hidden_dims != first.decoder.config().hidden_dims) {
        mismatch("the decoder's hidden layers", dims_text(tile.decoder.config().hidden_dims),
                 dims_text(first.decoder.config().hidden_dims));
    }
    const std::vector<float>& wa = tile.decoder.params();
    const std::vector<float>& wb = first.decoder.params();
    if (wa.size() != wb.size()) {
        mismatch("the number of decoder weights", std::to_string(wa.size()),
                 std::to_string(wb.size()));
    }
    for (std::size_t i = 0; i < wa.size(); ++i) {
        if (std::memcmp(&wa[i], &wb[i], sizeof(float)) != 0) {  // bit-identical, NaN included
            const auto [mine, theirs] = two_numbers({wa[i]}, {wb[i]});
            mismatch("the decoder (weight " + std::to_string(i) + ")", mine, theirs);
        }
    }
}

}  // namespace

double TileCore::distance_m(double x_m, double y_m) const {
    const double dx = std::max({x_min_m - x_m, 0.0, x_m - x_max_m});
    const double dy = std::max({y_min_m - y_m, 0.0, y_m - y_max_m});
    return std::hypot(dx, dy);
}

MapTile parse_tile_spec(const std::string& spec) {
    const std::string usage = "--tile '" + spec +
                              "': expected PATH:xmin,ymin,xmax,ymax (the tile's map.vdb and its "
                              "core box in world metres, e.g. t03/map.vdb:0,-40,40,0)";
    const std::size_t colon = spec.rfind(':');
    if (colon == std::string::npos || colon == 0) throw ConfigError(usage);
    MapTile tile;
    tile.map_path = spec.substr(0, colon);
    std::vector<double> bounds;
    std::stringstream numbers(spec.substr(colon + 1));
    std::string item;
    while (std::getline(numbers, item, ',')) {
        double v = 0.0;
        if (!parse_bound(item, v)) throw ConfigError(usage + "; '" + item + "' is not a number");
        bounds.push_back(v);
    }
    if (bounds.size() != 4) throw ConfigError(usage);
    tile.core_world_m = {bounds[0], bounds[1], bounds[2], bounds[3]};
    check_core(tile.core_world_m, "--tile '" + spec + "'");
    return tile;
}

std::vector<MapTile> read_tile_manifest(const fs::path& path) {
    if (!fs::is_regular_file(path)) {
        throw IoError("tile manifest '" + path.string() + "' does not exist");
    }
    YAML::Node root;
    try {
        root = YAML::LoadFile(path.string());
    } catch (const YAML::Exception& e) {
        throw IoError("tile manifest '" + path.string() + "' is not valid JSON/YAML: " + e.msg);
    }
    const std::string form =
        "; expected {\"tiles\": [{\"map\": \"PATH/map.vdb\", \"core_world_m\": [xmin, ymin, "
        "xmax, ymax]}, ...]}";
    if (!root.IsMap() || !root["tiles"] || !root["tiles"].IsSequence()) {
        throw IoError("tile manifest '" + path.string() + "' has no list 'tiles'" + form);
    }
    std::vector<MapTile> tiles;
    std::size_t index = 0;
    for (const YAML::Node& entry : root["tiles"]) {
        const std::string where =
            "tile manifest '" + path.string() + "', tile " + std::to_string(index++);
        try {
            if (!entry.IsMap() || !entry["map"] || !entry["map"].IsScalar() ||
                !entry["core_world_m"] || !entry["core_world_m"].IsSequence() ||
                entry["core_world_m"].size() != 4) {
                throw IoError(where + ": needs 'map' (a path) and 'core_world_m' (4 numbers)" +
                              form);
            }
            MapTile tile;
            tile.map_path = entry["map"].as<std::string>();
            if (tile.map_path.is_relative()) tile.map_path = path.parent_path() / tile.map_path;
            double b[4];
            for (int k = 0; k < 4; ++k) {
                const std::string text = entry["core_world_m"][k].as<std::string>();
                if (!parse_bound(text, b[k])) {
                    throw IoError(where + ": core_world_m value '" + text + "' is not a number");
                }
            }
            tile.core_world_m = {b[0], b[1], b[2], b[3]};
            try {
                check_core(tile.core_world_m, where);
            } catch (const ConfigError& e) {
                throw IoError(e.what());
            }
            tiles.push_back(tile);
        } catch (const YAML::Exception& e) {
            throw IoError(where + ": " + e.msg + form);
        }
    }
    if (tiles.empty()) throw IoError("tile manifest '" + path.string() + "' lists no tiles");
    return tiles;
}

void check_tile_cores(const std::vector<MapTile>& tiles) {
    std::set<fs::path> seen;
    for (const MapTile& t : tiles) {
        check_core(t.core_world_m, "tile '" + t.map_path.string() + "'");
        std::error_code ec;
        fs::path key = fs::weakly_canonical(t.map_path, ec);
        if (ec) key = t.map_path.lexically_normal();
        if (!seen.insert(key).second) {
            throw ConfigError("tile '" + t.map_path.string() + "' is listed twice");
        }
    }
    for (std::size_t i = 0; i < tiles.size(); ++i) {
        for (std::size_t j = i + 1; j < tiles.size(); ++j) {
            const TileCore& a = tiles[i].core_world_m;
            const TileCore& b = tiles[j].core_world_m;
            const double wx = std::min(a.x_max_m, b.x_max_m) - std::max(a.x_min_m, b.x_min_m);
            const double wy = std::min(a.y_max_m, b.y_max_m) - std::max(a.y_min_m, b.y_min_m);
            if (wx > 0.0 && wy > 0.0) {
                throw ConfigError("the cores of tiles '" + tiles[i].map_path.string() + "' " +
                                  core_text(a) + " and '" + tiles[j].map_path.string() + "' " +
                                  core_text(b) +
                                  " overlap; cores must partition the plane (the overlap belongs "
                                  "in the tiles' crop boxes, not their cores)");
            }
        }
    }
}

MergedMap merge_tile_maps(const std::vector<MapTile>& tiles) {
    if (tiles.empty()) throw ConfigError("merge: no tiles given");
    check_tile_cores(tiles);
    for (const MapTile& tile : tiles) {  // fail before the long part
        if (!fs::is_regular_file(tile.map_path)) {
            throw IoError("map file '" + tile.map_path.string() + "' does not exist");
        }
    }

    LoadedMap first = load_neural_map(tiles[0].map_path);
    const FeatureOctreeConfig cfg = first.sdf.octree.config();
    const int num_levels = cfg.num_levels;
    MergedMap merged{NeuralSdf(cfg, first.sdf.decoder.config()), first.config_text, {}};
    merged.sdf.decoder.params() = first.sdf.decoder.params();
    merged.sdf.origin_world_m = first.sdf.origin_world_m;
    const Eigen::Vector3d origin = first.sdf.origin_world_m;

    // Per level: corner -> merged row (background -1). Per merged row: the priority of the tile
    // its feature came from (-1 for the owner, else the distance to that tile's core) and the
    // tile's index. A later tile replaces a row only with a strictly better priority.
    std::vector<openvdb::Int32Grid::Ptr> merged_rows(num_levels);
    for (auto& g : merged_rows) g = openvdb::Int32Grid::create(-1);
    std::vector<double> priority;
    std::vector<std::uint32_t> source_tile;
    FeatureTable& table = merged.sdf.octree.features();
    merged.stats.tiles.resize(tiles.size());

    for (std::size_t t = 0; t < tiles.size(); ++t) {
        const MapTile& tile = tiles[t];
        LoadedMap loaded = t == 0 ? std::move(first) : load_neural_map(tile.map_path);
        if (t > 0) check_compatible(merged.sdf, tiles[0].map_path, loaded.sdf, tile.map_path);
        const FeatureOctree& octree = loaded.sdf.octree;
        merged.stats.tiles[t].map_path = tile.map_path;
        merged.stats.tiles[t].corners = octree.num_corners();

        struct Copy {
            std::int32_t src_row, dst_row;
        };
        std::vector<Copy> copies;
        std::size_t next_row = priority.size();
        for (int level = 0; level < num_levels; ++level) {
            const double cell_m = octree.cell_size_m(level);
            auto accessor = merged_rows[level]->getAccessor();
            for_each_corner(octree.impl().levels[level], [&](const openvdb::Coord& corner,
                                                             std::int32_t src_row) {
                const double x = origin.x() + corner.x() * cell_m;
                const double y = origin.y() + corner.y() * cell_m;
                const double p =
                    tile.core_world_m.contains(x, y) ? -1.0 : tile.core_world_m.distance_m(x, y);
                std::int32_t row = accessor.getValue(corner);
                if (row < 0) {
                    if (next_row >=
                        static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
                        throw DataError("merged map exceeds 2^31 corners");
                    }
                    row = static_cast<std::int32_t>(next_row++);
                    accessor.setValue(corner, row);
                    priority.push_back(p);
                    source_tile.push_back(static_cast<std::uint32_t>(t));
                    copies.push_back({src_row, row});
                } else if (p < priority[static_cast<std::size_t>(row)]) {
                    priority[static_cast<std::size_t>(row)] = p;
                    source_tile[static_cast<std::size_t>(row)] = static_cast<std::uint32_t>(t);
                    copies.push_back({src_row, row});
                }
            });
        }
        table.resize(next_row);
        for (const Copy& c : copies) {
            table.copy_rows(octree.features(), static_cast<std::size_t>(c.src_row),
                            static_cast<std::size_t>(c.dst_row), 1);
        }
    }

    for (std::size_t row = 0; row < priority.size(); ++row) {
        ++merged.stats.tiles[source_tile[row]].corners_taken;
        if (priority[row] >= 0.0) ++merged.stats.fallback_corners;
    }
    merged.stats.corners = priority.size();

    // The merged levels: topology from the corner -> row grids, as load_neural_map builds them.
    auto& levels = merged.sdf.octree.impl().levels;
    for (int level = 0; level < num_levels; ++level) {
        const openvdb::Int32Grid& rows = *merged_rows[level];
        LevelIndex& index = levels[level];
        if (rows.empty()) continue;
        index.shift = choose_index_shift(rows.evalActiveVoxelBoundingBox());
        index.shift_chosen = true;
        index.grid->transform().postTranslate(-index.shift.asVec3d() *
                                              merged.sdf.octree.cell_size_m(level));
        auto accessor = index.grid->getAccessor();
        for (auto it = rows.cbeginValueOn(); it; ++it) {
            accessor.setValueOn(it.getCoord() + index.shift);
        }
        auto row_accessor = rows.getConstAccessor();
        repack_rows(index, &index.grid->tree(),
                    [&](const openvdb::Coord& corner) { return row_accessor.getValue(corner); });
    }
    return merged;
}

}  // namespace shine
