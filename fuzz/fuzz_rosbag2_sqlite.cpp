// libFuzzer target: the rosbag2 sqlite reader (.db3 files), indexed, every message read and decoded
// as a PointCloud2 (fuzz_recording.hpp).
#include "fuzz_recording.hpp"
#include "shine/io/rosbag2_sqlite_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    shine_fuzz::read_recording_fully(data, size, ".db3", [](const std::filesystem::path& path) {
        return shine::open_rosbag2_sqlite(path);
    });
    return 0;
}
