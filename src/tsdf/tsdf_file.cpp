#include "shine/tsdf/tsdf_file.hpp"

#include <openvdb/io/File.h>

#include <string>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/io/vdb_file_check.hpp"

namespace shine {
namespace {

constexpr const char* kFormatKey = "shine_format";
constexpr const char* kFormatName = "shine_tsdf";

template <typename MetaT>
auto required(const openvdb::MetaMap& meta, const std::string& key,
              const std::filesystem::path& path)
    -> std::decay_t<decltype(std::declval<MetaT>().value())> {
    auto m = meta.getMetadata<MetaT>(key);
    if (!m) {
        throw IoError("'" + path.string() + "' is not a complete ShineVDB TSDF volume: metadata '" +
                      key + "' is missing or has the wrong type");
    }
    return m->value();
}

}  // namespace

void write_tsdf_volume(const std::filesystem::path& path, const TsdfVolume& volume) {
    openvdb::initialize();
    const TsdfConfig& config = volume.config();
    const Eigen::Vector3d& o = volume.origin_world_m();
    const openvdb::Vec3DMetadata origin(openvdb::Vec3d(o.x(), o.y(), o.z()));
    openvdb::MetaMap meta;
    meta.insertMeta(kFormatKey, openvdb::StringMetadata(kFormatName));
    meta.insertMeta("shine_voxel_size_m", openvdb::DoubleMetadata(config.voxel_size_m));
    meta.insertMeta("shine_trunc_m", openvdb::DoubleMetadata(config.trunc_m));
    meta.insertMeta("shine_space_carving", openvdb::BoolMetadata(config.space_carving));
    meta.insertMeta("shine_origin_world_m", origin);
    // Shallow copies that share the trees, so the metadata does not touch the volume's grids.
    openvdb::GridCPtrVec grids;
    for (const auto& grid : {volume.tsdf_grid_ptr(), volume.weight_grid_ptr()}) {
        openvdb::FloatGrid::Ptr copy = openvdb::ConstPtrCast<openvdb::FloatGrid>(grid)->copy();
        copy->insertMeta("shine_origin_world_m", origin);
        grids.push_back(copy);
    }
    write_file_atomically(path, [&](const std::filesystem::path& tmp) {
        try {
            openvdb::io::File file(tmp.string());
            file.write(grids, meta);
            file.close();
        } catch (const openvdb::Exception& e) {
            throw IoError("cannot write TSDF volume '" + path.string() + "': " + e.what());
        }
    });
}

TsdfVolume read_tsdf_volume(const std::filesystem::path& path) {
    openvdb::initialize();
    if (!std::filesystem::is_regular_file(path)) {
        throw IoError("TSDF volume file '" + path.string() + "' does not exist");
    }
    // A damaged file is reported with its byte offset before OpenVDB reads it.
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
        throw IoError("cannot read TSDF volume '" + path.string() + "': not a valid .vdb file (" +
                      e.what() + ")");
    }
    const auto format = meta->getMetadata<openvdb::StringMetadata>(kFormatKey);
    if (!format || format->value() != kFormatName) {
        throw IoError("'" + path.string() +
                      "' is a .vdb file but not a ShineVDB TSDF volume (no 'shine_format = " +
                      kFormatName + "' metadata); `shine tsdf` writes tsdf.vdb");
    }
    TsdfConfig config;
    config.voxel_size_m = required<openvdb::DoubleMetadata>(*meta, "shine_voxel_size_m", path);
    config.trunc_m = required<openvdb::DoubleMetadata>(*meta, "shine_trunc_m", path);
    config.space_carving = required<openvdb::BoolMetadata>(*meta, "shine_space_carving", path);
    const auto o = required<openvdb::Vec3DMetadata>(*meta, "shine_origin_world_m", path);
    openvdb::FloatGrid::Ptr tsdf, weight;
    for (const auto& g : *grids) {
        auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
        if (!grid) continue;
        if (grid->getName() == "tsdf") tsdf = grid;
        if (grid->getName() == "weight") weight = grid;
    }
    if (!tsdf || !weight) {
        throw IoError("'" + path.string() + "' lacks the float grid '" +
                      std::string(!tsdf ? "tsdf" : "weight") + "'");
    }
    for (const auto& grid : {tsdf, weight}) grid->removeMeta("shine_origin_world_m");
    try {
        return TsdfVolume(config, Eigen::Vector3d(o.x(), o.y(), o.z()), tsdf, weight);
    } catch (const Error& e) {
        throw IoError("'" + path.string() + "': " + e.what());
    }
}

}  // namespace shine
