// ROS 1 bags (format 2.0): the record layout of http://wiki.ros.org/Bags/Format/2.0, read by our
// own code (docs/recordings.md says why not librosbag-storage).
//
// Opening walks the file's records once: chunks are decompressed one at a time (bz2, or lz4 in
// the LZ4 frame format that roslz4 writes) to find their connection and message records; only
// each message's chunk offset, offset inside the chunk and time are kept. Reading a message
// decompresses its chunk (the last chunk is cached). The index records at the end of the file are
// not needed (an unindexed bag whose records are whole opens too); a record running past the end
// of the file is an IoError.
#pragma once

#include <filesystem>
#include <memory>

#include "shine/io/recording.hpp"

namespace shine {

/// Opens a ROS 1 bag. Throws IoError naming the file, the byte offset and the problem (not a bag,
/// version other than 2.0, truncated or corrupt record, unknown compression).
std::unique_ptr<RecordingReader> open_rosbag1(const std::filesystem::path& path);

}  // namespace shine
