// libFuzzer target: the mcap reader (.mcap files), indexed, every message read and decoded as a
// PointCloud2 (fuzz_recording.hpp).
#include "fuzz_recording.hpp"
#include "shine/io/mcap_reader.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    shine_fuzz::read_recording_fully(data, size, ".mcap", [](const std::filesystem::path& path) {
        return shine::open_mcap(path);
    });
    return 0;
}
