// libFuzzer target: checkpoints (OUT/checkpoint.bin), as `shine map --resume` reads them: the
// header, then the state into mappers whose maps were rebuilt from the same scans (here two small
// synthetic scans, so that valid-looking states reach every load step; the sequence-level records
// after the mapper's state, the stage profile and the progress meshes, are plain arrays read by
// the same BinaryReader and are left out). Any outcome but a restored state or a shine::Error
// naming the file is a bug.
//
// `fuzz_checkpoint --write-seeds DIR` writes a valid batch and incremental checkpoint of these
// mappers as seeds (fuzz/corpus/fuzz_checkpoint/).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>

#include "fuzz_common.hpp"
#include "shine/mapper/batch_mapper.hpp"
#include "shine/mapper/checkpoint.hpp"
#include "shine/mapper/incremental_mapper.hpp"

namespace {

/// A ring of points around the sensor and a ground patch: enough for a few hundred corners.
shine::Scan synthetic_scan(double x_m) {
    shine::Scan scan;
    for (int i = 0; i < 360; ++i) {
        const float a = static_cast<float>(i) * 0.01745329f;
        scan.points_sensor.emplace_back(6.0f * std::cos(a), 6.0f * std::sin(a), 0.5f);
        scan.points_sensor.emplace_back(3.0f * std::cos(a), 3.0f * std::sin(a), -1.7f);
    }
    scan.T_world_sensor.translation() = Eigen::Vector3d(x_m, 0.0, 1.7);
    scan.source = "synthetic";
    return scan;
}

shine::MapperConfig small_config() {
    shine::MapperConfig config;
    config.octree.leaf_size_m = 0.5;
    config.incremental.iterations_per_frame = 2;
    config.trainer.batch_size = 256;
    config.iterations = 2;
    return config;
}

struct Mappers {
    std::unique_ptr<shine::BatchMapper> batch;
    std::unique_ptr<shine::IncrementalMapper> incremental;
};

/// Mappers as a resumed run has them before load_state(): scans added (batch) or replayed.
Mappers rebuilt_mappers() {
    Mappers m;
    m.batch = std::make_unique<shine::BatchMapper>(small_config());
    m.incremental = std::make_unique<shine::IncrementalMapper>(small_config());
    for (double x : {0.0, 1.0}) {
        m.batch->add_scan(synthetic_scan(x));
        m.incremental->replay_scan(synthetic_scan(x));
    }
    return m;
}

int write_seeds(const std::filesystem::path& dir) {
    std::filesystem::create_directories(dir);
    shine::BatchMapper batch(small_config());
    shine::IncrementalMapper incremental(small_config());
    for (double x : {0.0, 1.0}) {
        batch.add_scan(synthetic_scan(x));
        incremental.add_scan(synthetic_scan(x));
    }
    batch.train();
    shine::write_checkpoint(dir / "batch.bin", "{\"seed\": \"batch\"}",
                            shine::CheckpointMode::kBatch, [&](shine::BinaryWriter& out) {
                                out.value<std::uint8_t>(1);  // phase: training
                                batch.save_state(out);
                            });
    shine::write_checkpoint(dir / "incremental.bin", "{\"seed\": \"incremental\"}",
                            shine::CheckpointMode::kIncremental, [&](shine::BinaryWriter& out) {
                                out.value<std::uint64_t>(2);  // frames done
                                incremental.save_state(out);
                            });
    std::printf("wrote %s/{batch,incremental}.bin\n", dir.c_str());
    return 0;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
    for (int i = 1; i + 1 < *argc; ++i) {
        if (std::strcmp((*argv)[i], "--write-seeds") == 0) std::exit(write_seeds((*argv)[i + 1]));
    }
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static shine_fuzz::ScratchFile scratch(".checkpoint");
    // Fresh mappers for every input: a failed load may leave a mapper half restored, which the
    // CLI never reuses either.
    Mappers m = rebuilt_mappers();
    const std::filesystem::path& path = scratch.write(shine_fuzz::as_view(data, size));
    try {
        std::string description;
        shine::CheckpointMode mode;
        shine::BinaryReader in = shine::read_checkpoint_header(path, description, mode);
        // The sections map_sequence() and map_sequence_incremental() read first.
        if (mode == shine::CheckpointMode::kBatch) {
            if (in.value<std::uint8_t>("phase") == 1) m.batch->load_state(in);
        } else {
            in.value<std::uint64_t>("frames done");
            m.incremental->load_state(in);
        }
        in.expect_end();
    } catch (const shine::Error& e) {
        if (std::string(e.what()).find(path.filename().string()) == std::string::npos) {
            std::fprintf(stderr, "error message does not name the file: %s\n", e.what());
            std::abort();
        }
    }
    return 0;
}
