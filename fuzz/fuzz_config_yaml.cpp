// libFuzzer target: the YAML configuration (`shine map -c config.yaml`).
#include "fuzz_common.hpp"
#include "shine/mapper/mapper_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string text(reinterpret_cast<const char*>(data), size);
    shine::MapperConfig config;
    bool parsed = false;
    shine_fuzz::expect_value_or_error([&] {
        shine::parse_config_yaml(text, shine_fuzz::kSource.string(), config);
        parsed = true;
    });
    if (!parsed) return 0;
    // A configuration that was accepted is written into map.vdb and must read back.
    shine::MapperConfig again;
    try {
        shine::parse_config_yaml(shine::config_to_yaml(config), "round trip", again);
    } catch (const shine::Error& e) {
        std::fprintf(stderr, "accepted configuration does not read back: %s\n", e.what());
        std::abort();
    }
    // The cross-key checks run when a mapper starts; they may reject, but only with an Error.
    try {
        config.finalize();
    } catch (const shine::Error&) {
    }
    return 0;
}
