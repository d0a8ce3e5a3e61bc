// Structure check of an OpenVDB file (header, metadata, grid descriptors) before OpenVDB reads it.
//
// OpenVDB's reader trusts the sizes it finds in a file: a damaged string or metadata length makes
// it allocate up to 4 GB, a metadata entry whose byte count does not match its type puts every
// later read out of step, and a grid offset past the end makes it read garbage. This check reads
// only the structure, with every length and offset bounded by the file size, so a truncated or
// corrupt file is reported with its byte offset instead of crashing or exhausting memory. It
// does not decompress voxel data (OpenVDB checks that itself and throws) and needs no OpenVDB.
//
// Layout (OpenVDB file format 222 and later, i.e. OpenVDB 3 onwards; little endian):
//   int64 magic 0x56444220 ("VDB "), uint32 format version, uint32 library major, minor,
//   uint8 has_grid_offsets, char[36] uuid, file metadata (MetaMap), int32 grid count,
//   per grid: string unique name, string type, string instance parent,
//             int64 grid position, int64 block position, int64 end position;
//   at each grid position: uint32 compression flags, grid metadata (MetaMap), transform, topology;
//   voxel buffers from the block position to the end position; the next descriptor follows.
// A string is a uint32 length and that many bytes; a MetaMap is an int32 count and per entry a
// name, a type name, a uint32 byte count and the value bytes.
// (blender_addon/shinevdb/vdb_header.py does the same check in Python.)
#pragma once

#include <cstdint>
#include <filesystem>
#include <iosfwd>
#include <string>
#include <string_view>
#include <vector>

namespace shine {

/// What the file says about one grid, without reading its voxels.
struct VdbGridInfo {
    std::string name;         ///< grid name (OpenVDB's "\x1e<n>" suffix of repeated names removed)
    std::string type;         ///< tree type, e.g. "Tree_float_5_4_3" ("_HalfFloat" removed)
    std::string grid_class;   ///< "level set", "fog volume", "staggered" or "unknown"
    bool half_float = false;  ///< floats stored as halves
    std::uint64_t grid_offset = 0;
    std::uint64_t end_offset = 0;
};

/// The structure check_vdb_file found.
struct VdbFileInfo {
    std::uint32_t format_version = 0;
    std::vector<std::string> file_metadata;  ///< names of the file-level metadata entries
    std::vector<VdbGridInfo> grids;
};

/// Checks the structure of the OpenVDB file at `path`. Throws IoError
/// "<kind> '<path>', byte offset N: <problem>" when the file is missing, not an OpenVDB file, of
/// an unsupported format version, truncated, or has a length, count or offset that does not fit
/// the file, or a metadata entry whose size does not match its type.
VdbFileInfo check_vdb_file(const std::filesystem::path& path,
                           const std::string& kind = "OpenVDB file");

/// check_vdb_file on bytes already in memory; `source` names them in messages.
VdbFileInfo check_vdb_bytes(std::string_view data, const std::filesystem::path& source,
                            const std::string& kind = "OpenVDB file");

}  // namespace shine
