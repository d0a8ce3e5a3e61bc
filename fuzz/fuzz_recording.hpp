// Shared body of the recording fuzz targets: a recording read the way ScanSequence reads it
// (open and index, list topics, then every message of every topic read and decoded as a
// PointCloud2). Recordings are read from paths, so every input goes through a scratch file;
// an error must name that file.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include "fuzz_common.hpp"
#include "shine/io/point_cloud2.hpp"
#include "shine/io/recording.hpp"

namespace shine_fuzz {

template <class Open>
void read_recording_fully(const std::uint8_t* data, std::size_t size, const std::string& extension,
                          Open&& open) {
    static ScratchFile scratch(extension);
    const std::filesystem::path& path = scratch.write(as_view(data, size));
    try {
        const std::unique_ptr<shine::RecordingReader> reader = open(path);
        for (const shine::RecordingTopic& topic : reader->topics()) {
            std::size_t n = 0;
            for (const shine::RecordingMessage& m : reader->messages(topic.name)) {
                const std::string where = path.string() + ", message " + std::to_string(n++);
                const std::string bytes = reader->read(m);
                shine::decode_header_stamp_s(reader->read_prefix(m, 16), topic.encoding, where);
                shine::decode_point_cloud2(bytes, topic.encoding, where);
            }
        }
    } catch (const shine::Error& e) {
        if (std::string(e.what()).find(path.filename().string()) == std::string::npos) {
            std::fprintf(stderr, "error message does not name the file: %s\n", e.what());
            std::abort();
        }
    }
}

}  // namespace shine_fuzz
