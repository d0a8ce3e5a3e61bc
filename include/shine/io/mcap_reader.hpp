// MCAP files (https://mcap.dev/spec, version 0): magic, records (opcode u8, length u64, body),
// magic. Read by our own code: Debian 12 packages no MCAP library.
//
// Opening walks the data section once: Schema and Channel records are kept, chunks (compression
// "", "lz4" (LZ4 frame) or "zstd") are decompressed one at a time to find their Message records;
// only each message's location and log time are kept. The summary section is not needed (it is
// optional in the spec). Reading a message decompresses its chunk (the last chunk is cached).
#pragma once

#include <filesystem>
#include <memory>

#include "shine/io/recording.hpp"

namespace shine {

/// Opens an MCAP file. Throws IoError naming the file, the byte offset and the problem (bad
/// magic, truncated or corrupt record, unknown compression, a chunk whose CRC-32 does not match;
/// a CRC of 0 means "not computed" and is not checked).
std::unique_ptr<RecordingReader> open_mcap(const std::filesystem::path& path);

}  // namespace shine
