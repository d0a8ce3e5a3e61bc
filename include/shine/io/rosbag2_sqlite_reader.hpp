// ROS 2 bags stored by rosbag2's sqlite3 plugin (.db3): tables `topics(id, name, type,
// serialization_format, ...)` and `messages(id, topic_id, timestamp, data)`, read with Debian's
// libsqlite3 (read-only, immutable: the file is never changed). Several files of one bag are read
// in the order metadata.yaml lists them.
#pragma once

#include <filesystem>
#include <memory>
#include <vector>

#include "shine/io/recording.hpp"

namespace shine {

/// Opens one .db3 file. Throws IoError naming the file and the problem (not SQLite, no rosbag2
/// tables, corrupt database).
std::unique_ptr<RecordingReader> open_rosbag2_sqlite(const std::filesystem::path& path);

}  // namespace shine
