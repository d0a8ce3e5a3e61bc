#include "shine/bake/level_set_file.hpp"

#include <openvdb/io/File.h>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"
#include "shine/io/vdb_file_check.hpp"

namespace shine {

void write_level_set(const std::filesystem::path& path, const openvdb::FloatGrid::Ptr& grid) {
    openvdb::initialize();
    write_file_atomically(path, [&](const std::filesystem::path& tmp) {
        try {
            openvdb::io::File file(tmp.string());
            file.write({grid});
            file.close();
        } catch (const openvdb::Exception& e) {
            throw IoError("cannot write level set '" + path.string() + "': " + e.what());
        }
    });
}

openvdb::FloatGrid::Ptr read_level_set(const std::filesystem::path& path) {
    openvdb::initialize();
    if (!std::filesystem::is_regular_file(path)) {
        throw IoError("level set file '" + path.string() + "' does not exist");
    }
    // A damaged file is reported with its byte offset before OpenVDB reads it (see map_file.cpp).
    check_vdb_file(path);
    openvdb::GridPtrVecPtr grids;
    try {
        openvdb::io::File file(path.string());
        file.open(false);
        grids = file.getGrids();
        file.close();
    } catch (const std::exception& e) {
        throw IoError("cannot read '" + path.string() + "': not a valid .vdb file (" + e.what() +
                      ")");
    }
    for (const auto& g : *grids) {
        auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
        if (grid && grid->getGridClass() == openvdb::GRID_LEVEL_SET) return grid;
    }
    throw IoError("'" + path.string() +
                  "' holds no float grid of class LEVEL_SET (is it a neural map.vdb? use "
                  "`shine bake` to make a surface from it)");
}

}  // namespace shine
