#include "shine/model/map_file.hpp"

#include <openvdb/io/File.h>

#include <algorithm>
#include <cstring>
#include <memory>
#include <mutex>
#include <type_traits>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/io/vdb_file_check.hpp"
#include "shine/map/feature_octree_impl.hpp"

namespace shine {
namespace {

constexpr char kFormatKey[] = "shine_format";
constexpr char kFormatName[] = "shine-neural-map-1";

/// OpenVDB metadata holding an array of T (feature table, decoder weights): "shine_float_array"
/// (float32) or "shine_half_array" (float16, little-endian IEEE half as OpenVDB writes halves).
/// Tools that do not know the type keep it as opaque bytes, so the file stays readable by
/// vdb_print.
///
/// The values are either owned (read from a file, or moved in) and shared by copies, or a view of
/// an array the caller keeps alive (writing): OpenVDB copies metadata on insertion, and a copy of
/// a city's feature table would double its memory just to save it.
template <typename T>
class ArrayMetadata : public openvdb::Metadata {
  public:
    using Ptr = openvdb::SharedPtr<ArrayMetadata>;
    static const char* type_name() {
        return std::is_same_v<T, float> ? "shine_float_array" : "shine_half_array";
    }

    ArrayMetadata() = default;
    explicit ArrayMetadata(std::vector<T> values)
        : owned_(std::make_shared<const std::vector<T>>(std::move(values))),
          data_(owned_->data()),
          count_(owned_->size()) {}
    /// Refers to `count` values at `data` without copying them; they must outlive this metadata
    /// and every copy of it.
    ArrayMetadata(const T* data, std::size_t count) : data_(data), count_(count) {}

    const T* begin() const { return data_; }
    const T* end() const { return data_ + count_; }
    std::size_t count() const { return count_; }

    static openvdb::Name staticTypeName() { return type_name(); }
    openvdb::Name typeName() const override { return type_name(); }
    openvdb::Metadata::Ptr copy() const override {
        auto result = std::make_shared<ArrayMetadata>(data_, count_);
        result->owned_ = owned_;
        return result;
    }
    void copy(const openvdb::Metadata& other) override {
        const auto* o = dynamic_cast<const ArrayMetadata*>(&other);
        if (!o) OPENVDB_THROW(openvdb::TypeError, "incompatible metadata type");
        owned_ = o->owned_;
        data_ = o->data_;
        count_ = o->count_;
    }
    std::string str() const override {
        return std::string(std::is_same_v<T, float> ? "float" : "half") + "[" +
               std::to_string(count_) + "]";
    }
    bool asBool() const override { return count_ > 0; }
    openvdb::Index32 size() const override {
        return static_cast<openvdb::Index32>(count_ * sizeof(T));
    }
    static openvdb::Metadata::Ptr create() { return openvdb::Metadata::Ptr(new ArrayMetadata); }

  protected:
    void readValue(std::istream& is, openvdb::Index32 num_bytes) override {
        if (num_bytes % sizeof(T) != 0) {
            OPENVDB_THROW(openvdb::IoError, type_name()
                                                << " metadata of " << num_bytes << " bytes");
        }
        auto values = std::make_shared<std::vector<T>>(num_bytes / sizeof(T));
        is.read(reinterpret_cast<char*>(values->data()), num_bytes);
        if (!is) OPENVDB_THROW(openvdb::IoError, "truncated " << type_name() << " metadata");
        owned_ = std::move(values);
        data_ = owned_->data();
        count_ = owned_->size();
    }
    void writeValue(std::ostream& os) const override {
        os.write(reinterpret_cast<const char*>(data_), size());
    }

  private:
    std::shared_ptr<const std::vector<T>> owned_;  ///< null for a view
    const T* data_ = nullptr;
    std::size_t count_ = 0;
};

using FloatArrayMetadata = ArrayMetadata<float>;
using HalfArrayMetadata = ArrayMetadata<Imath::half>;
static_assert(sizeof(Imath::half) == 2, "half must be 2 bytes");

void register_metadata_types() {
    static std::once_flag once;
    std::call_once(once, [] {
        openvdb::initialize();
        if (!openvdb::Metadata::isRegisteredType(FloatArrayMetadata::type_name())) {
            openvdb::Metadata::registerType(FloatArrayMetadata::type_name(),
                                            FloatArrayMetadata::create);
        }
        if (!openvdb::Metadata::isRegisteredType(HalfArrayMetadata::type_name())) {
            openvdb::Metadata::registerType(HalfArrayMetadata::type_name(),
                                            HalfArrayMetadata::create);
        }
    });
}

template <typename MetaT>
auto required(const openvdb::MetaMap& meta, const std::string& key,
              const std::filesystem::path& path)
    -> std::decay_t<decltype(std::declval<MetaT>().value())> {
    auto m = meta.getMetadata<MetaT>(key);
    if (!m) {
        throw IoError("'" + path.string() + "' is not a complete ShineVDB map: metadata '" + key +
                      "' is missing or has the wrong type");
    }
    return m->value();
}

std::string shift_key(int level) { return "shine_level_" + std::to_string(level) + "_index_shift"; }

/// The level's corners as a standard Int32Grid (OpenVDB's default 5-4-3 tree, registered
/// everywhere): voxel = corner (unshifted), value = feature row, background -1.
openvdb::Int32Grid::Ptr to_int32_grid(const LevelIndex& level, double cell_size_m) {
    auto grid = openvdb::Int32Grid::create(-1);
    grid->setName(level.grid->getName());
    grid->setTransform(openvdb::math::Transform::createLinearTransform(cell_size_m));
    grid->setGridClass(openvdb::GRID_UNKNOWN);
    auto accessor = grid->getAccessor();
    for (auto leaf = level.grid->tree().cbeginLeaf(); leaf; ++leaf) {
        std::size_t slot = level.leaves[leaf->transientData()].first_slot;
        for (auto voxel = leaf->cbeginValueOn(); voxel; ++voxel) {
            accessor.setValue(voxel.getCoord() - level.shift, level.rows[slot++]);
        }
    }
    return grid;
}

}  // namespace

void save_neural_map(const std::filesystem::path& path, const NeuralSdf& sdf,
                     const std::string& config_text) {
    register_metadata_types();
    const FeatureOctree& octree = sdf.octree;
    const auto& cfg = octree.config();
    openvdb::MetaMap meta;
    meta.insertMeta(kFormatKey, openvdb::StringMetadata(kFormatName));
    meta.insertMeta("shine_leaf_size_m", openvdb::DoubleMetadata(cfg.leaf_size_m));
    meta.insertMeta("shine_num_levels", openvdb::Int32Metadata(cfg.num_levels));
    meta.insertMeta("shine_feature_dim", openvdb::Int32Metadata(cfg.feature_dim));
    meta.insertMeta("shine_init_std", openvdb::FloatMetadata(cfg.init_std));
    meta.insertMeta("shine_allocation_margin_ratio",
                    openvdb::DoubleMetadata(cfg.allocation_margin_ratio));
    meta.insertMeta("shine_seed", openvdb::Int64Metadata(static_cast<openvdb::Int64>(cfg.seed)));
    meta.insertMeta("shine_num_corners",
                    openvdb::Int64Metadata(static_cast<openvdb::Int64>(octree.num_corners())));
    const FeatureTable& features = octree.features();
    meta.insertMeta("shine_interpolation", openvdb::StringMetadata(to_string(cfg.interpolation)));
    meta.insertMeta("shine_feature_precision",
                    openvdb::StringMetadata(to_string(features.precision())));
    if (features.precision() == FeaturePrecision::kFloat16) {
        meta.insertMeta("shine_features", HalfArrayMetadata(features.halves(), features.size()));
    } else {
        meta.insertMeta("shine_features", FloatArrayMetadata(features.floats(), features.size()));
    }
    const auto& levels = octree.impl().levels;
    for (int level = 0; level < cfg.num_levels; ++level) {
        meta.insertMeta(shift_key(level), openvdb::Vec3IMetadata(levels[level].shift.asVec3i()));
    }
    std::string hidden;
    for (int h : sdf.decoder.config().hidden_dims)
        hidden += (hidden.empty() ? "" : ",") + std::to_string(h);
    meta.insertMeta("shine_decoder_hidden_dims", openvdb::StringMetadata(hidden));
    meta.insertMeta("shine_decoder_weights", FloatArrayMetadata(sdf.decoder.params()));
    meta.insertMeta("shine_origin_world_m",
                    openvdb::Vec3DMetadata(openvdb::Vec3d(
                        sdf.origin_world_m.x(), sdf.origin_world_m.y(), sdf.origin_world_m.z())));
    meta.insertMeta("shine_config", openvdb::StringMetadata(config_text));

    openvdb::GridPtrVec grids;
    for (int level = 0; level < cfg.num_levels; ++level) {
        grids.push_back(to_int32_grid(levels[level], octree.cell_size_m(level)));
    }
    write_file_atomically(path, [&](const std::filesystem::path& tmp) {
        try {
            openvdb::io::File file(tmp.string());
            file.write(grids, meta);
            file.close();
        } catch (const openvdb::Exception& e) {
            throw IoError("cannot write map '" + path.string() + "': " + e.what());
        }
    });
}

LoadedMap load_neural_map(const std::filesystem::path& path) {
    register_metadata_types();
    if (!std::filesystem::is_regular_file(path)) {
        throw IoError("map file '" + path.string() + "' does not exist");
    }
    // OpenVDB trusts the sizes inside a file (docs/reliability.md): a damaged file is reported
    // here with its byte offset and never reaches OpenVDB's reader.
    check_vdb_file(path);
    openvdb::GridPtrVecPtr grids;
    openvdb::MetaMap::Ptr meta;
    try {
        openvdb::io::File file(path.string());
        file.open(false);
        grids = file.getGrids();
        meta = file.getMetadata();
        file.close();
    } catch (const std::exception& e) {
        throw IoError("cannot read map '" + path.string() + "': not a valid .vdb file (" +
                      e.what() + ")");
    }
    const auto format = meta->getMetadata<openvdb::StringMetadata>(kFormatKey);
    if (!format || format->value() != kFormatName) {
        throw IoError("'" + path.string() + "' is a .vdb file but not a ShineVDB neural map (no '" +
                      kFormatKey + "' metadata); did you pass surface.vdb instead of map.vdb?");
    }
    FeatureOctreeConfig cfg;
    cfg.leaf_size_m = required<openvdb::DoubleMetadata>(*meta, "shine_leaf_size_m", path);
    cfg.num_levels = required<openvdb::Int32Metadata>(*meta, "shine_num_levels", path);
    cfg.feature_dim = required<openvdb::Int32Metadata>(*meta, "shine_feature_dim", path);
    cfg.init_std = required<openvdb::FloatMetadata>(*meta, "shine_init_std", path);
    cfg.allocation_margin_ratio =
        required<openvdb::DoubleMetadata>(*meta, "shine_allocation_margin_ratio", path);
    cfg.seed =
        static_cast<std::uint64_t>(required<openvdb::Int64Metadata>(*meta, "shine_seed", path));
    // Maps written before half-precision features existed hold float32 features.
    cfg.feature_precision = FeaturePrecision::kFloat32;
    if (auto precision = meta->getMetadata<openvdb::StringMetadata>("shine_feature_precision")) {
        try {
            cfg.feature_precision =
                parse_feature_precision(precision->value(), "shine_feature_precision");
        } catch (const ConfigError& e) {
            throw IoError("'" + path.string() + "': " + e.what());
        }
    }
    // Maps written before the interpolation could be chosen used smoothstep weights.
    cfg.interpolation = Interpolation::kSmoothstep;
    if (auto interpolation = meta->getMetadata<openvdb::StringMetadata>("shine_interpolation")) {
        try {
            cfg.interpolation = parse_interpolation(interpolation->value(), "shine_interpolation");
        } catch (const ConfigError& e) {
            throw IoError("'" + path.string() + "': " + e.what());
        }
    }
    DecoderConfig decoder_cfg;
    decoder_cfg.input_dim = cfg.feature_dim;
    decoder_cfg.hidden_dims.clear();
    const std::string hidden =
        required<openvdb::StringMetadata>(*meta, "shine_decoder_hidden_dims", path);
    try {
        std::size_t pos = 0;
        while (pos < hidden.size()) {
            const std::size_t comma = hidden.find(',', pos);
            decoder_cfg.hidden_dims.push_back(std::stoi(hidden.substr(pos, comma - pos)));
            pos = comma == std::string::npos ? hidden.size() : comma + 1;
        }
    } catch (const std::exception&) {
        throw IoError("'" + path.string() + "': malformed decoder layer list '" + hidden + "'");
    }
    LoadedMap loaded{
        [&] {
            try {
                return NeuralSdf(cfg, decoder_cfg);
            } catch (const ConfigError& e) {
                throw IoError("'" + path.string() + "': invalid map parameters: " + e.what());
            } catch (const openvdb::Exception& e) {
                throw IoError("'" + path.string() + "': invalid map parameters: " + e.what());
            }
        }(),
        required<openvdb::StringMetadata>(*meta, "shine_config", path)};
    NeuralSdf& sdf = loaded.sdf;

    auto weights = meta->getMetadata<FloatArrayMetadata>("shine_decoder_weights");
    if (!weights || weights->count() != sdf.decoder.num_params()) {
        throw IoError("'" + path.string() + "': decoder weights missing or of the wrong size");
    }
    sdf.decoder.params().assign(weights->begin(), weights->end());
    const auto num_corners = required<openvdb::Int64Metadata>(*meta, "shine_num_corners", path);
    FeatureTable file_table(cfg.feature_dim, cfg.feature_precision);
    {
        bool sized = false;
        const std::size_t expected =
            num_corners < 0 ? 0 : static_cast<std::size_t>(num_corners) * cfg.feature_dim;
        if (cfg.feature_precision == FeaturePrecision::kFloat16) {
            auto features = meta->getMetadata<HalfArrayMetadata>("shine_features");
            sized = features && num_corners >= 0 && features->count() == expected;
            if (sized) {
                file_table.resize(static_cast<std::size_t>(num_corners));
                std::copy(features->begin(), features->end(), file_table.halves());
            }
        } else {
            auto features = meta->getMetadata<FloatArrayMetadata>("shine_features");
            sized = features && num_corners >= 0 && features->count() == expected;
            if (sized) {
                file_table.resize(static_cast<std::size_t>(num_corners));
                std::copy(features->begin(), features->end(), file_table.floats());
            }
        }
        if (!sized) {
            throw IoError("'" + path.string() + "': " + to_string(cfg.feature_precision) +
                          " feature table missing or of the wrong size");
        }
        meta->removeMeta("shine_features");  // the table holds them now
    }
    const auto origin = required<openvdb::Vec3DMetadata>(*meta, "shine_origin_world_m", path);
    sdf.origin_world_m = Eigen::Vector3d(origin.x(), origin.y(), origin.z());
    if (!sdf.origin_world_m.allFinite()) {
        throw IoError("'" + path.string() +
                      "': the map origin 'shine_origin_world_m' is not finite");
    }

    // Rebuild each level's topology (shifted index space) and packed rows from its Int32Grid;
    // every corner keeps the row the file gives it, so the table is used as stored.
    auto& levels = sdf.octree.impl().levels;
    std::vector<std::uint8_t> used(static_cast<std::size_t>(num_corners), 0);
    std::size_t corner_total = 0;
    for (int level = 0; level < cfg.num_levels; ++level) {
        const std::string name = "feature_level_" + std::to_string(level);
        openvdb::Int32Grid::Ptr found;
        for (const auto& g : *grids) {
            if (g->getName() == name) found = openvdb::gridPtrCast<openvdb::Int32Grid>(g);
        }
        if (!found) throw IoError("'" + path.string() + "': grid '" + name + "' is missing");
        for (auto it = found->cbeginValueOn(); it; ++it) {
            if (*it < 0 || *it >= num_corners) {
                throw IoError("'" + path.string() + "': grid '" + name +
                              "' refers to feature row " + std::to_string(*it) + " of " +
                              std::to_string(num_corners));
            }
            if (used[*it]) {
                throw IoError("'" + path.string() + "': feature row " + std::to_string(*it) +
                              " belongs to more than one corner");
            }
            used[*it] = 1;
        }
        corner_total += found->activeVoxelCount();
        LevelIndex& index = levels[level];
        if (auto shift = meta->getMetadata<openvdb::Vec3IMetadata>(shift_key(level))) {
            index.shift = openvdb::Coord(shift->value());
        } else if (!found->empty()) {  // maps written before the shift existed
            index.shift = choose_index_shift(found->evalActiveVoxelBoundingBox());
        }
        index.shift_chosen = !found->empty();
        index.grid->transform().postTranslate(-index.shift.asVec3d() *
                                              sdf.octree.cell_size_m(level));
        auto accessor = index.grid->getAccessor();
        for (auto it = found->cbeginValueOn(); it; ++it) {
            accessor.setValueOn(it.getCoord() + index.shift);
        }
        auto file_accessor = found->getConstAccessor();
        repack_rows(index, &index.grid->tree(),
                    [&](const openvdb::Coord& corner) { return file_accessor.getValue(corner); });
    }
    if (corner_total != static_cast<std::size_t>(num_corners)) {
        throw IoError("'" + path.string() + "': grids hold " + std::to_string(corner_total) +
                      " corners but the feature table has " + std::to_string(num_corners));
    }
    sdf.octree.features() = std::move(file_table);
    return loaded;
}

std::size_t file_bytes(const std::filesystem::path& path) {
    std::error_code ec;
    const auto size = std::filesystem::file_size(path, ec);
    return ec ? 0 : static_cast<std::size_t>(size);
}

}  // namespace shine
