// Reading and writing the surface .vdb (one float level-set grid).
#pragma once

#include <openvdb/openvdb.h>

#include <filesystem>

namespace shine {

/// Writes the level set to `path` atomically (temporary file + rename).
void write_level_set(const std::filesystem::path& path, const openvdb::FloatGrid::Ptr& grid);

/// Reads the first float grid of class LEVEL_SET from `path`. Throws IoError naming the file if it
/// is missing, not a .vdb, or holds no float level set.
openvdb::FloatGrid::Ptr read_level_set(const std::filesystem::path& path);

}  // namespace shine
