#include "shine/mapper/checkpoint.hpp"

#include <cstdint>

#include "shine/core/atomic_file.hpp"
#include "shine/core/error.hpp"

namespace shine {
namespace {
const std::string kMagic = "SHINE-CHECKPOINT";
// 4: a batch map's feature rows in tree order (a version-3 checkpoint's rows would be read into
// the wrong corners); 3: frame statistics say whether trained (keyframes).
constexpr std::uint32_t kFormatVersion = 4;
constexpr std::uint32_t kByteOrderMark = 0x01020304u;
}  // namespace

void write_checkpoint(const std::filesystem::path& path, const std::string& run_description,
                      CheckpointMode mode, const std::function<void(BinaryWriter&)>& write_state) {
    write_stream_atomically(path, [&](std::ostream& stream) {
        BinaryWriter out(stream);
        out.tag(kMagic);
        out.value<std::uint32_t>(kFormatVersion);
        out.value<std::uint32_t>(kByteOrderMark);
        out.string(run_description);
        out.value<std::uint8_t>(static_cast<std::uint8_t>(mode));
        write_state(out);
    });
}

BinaryReader read_checkpoint_header(const std::filesystem::path& path, std::string& run_description,
                                    CheckpointMode& mode) {
    BinaryReader in(path, "checkpoint");
    if (!in.next_is_tag(kMagic)) {
        in.fail("the header",
                "is not a ShineVDB checkpoint's (the file does not begin with " + kMagic + ")");
    }
    in.expect_tag(kMagic);
    const auto version = in.value<std::uint32_t>("format version");
    if (version != kFormatVersion) {
        in.fail("format version", std::to_string(version) + " is not this build's " +
                                      std::to_string(kFormatVersion) +
                                      " (resume with the build that wrote it)");
    }
    if (in.value<std::uint32_t>("byte-order mark") != kByteOrderMark) {
        in.fail("byte-order mark",
                "differs: the file was written on a machine of another byte order");
    }
    run_description = in.string("run description");
    const auto m = in.value<std::uint8_t>("mode");
    if (m != static_cast<std::uint8_t>(CheckpointMode::kBatch) &&
        m != static_cast<std::uint8_t>(CheckpointMode::kIncremental)) {
        in.fail("mode", std::to_string(m) + " is neither batch (1) nor incremental (2)");
    }
    mode = static_cast<CheckpointMode>(m);
    return in;
}

std::string read_checkpoint_description(const std::filesystem::path& path) {
    std::string description;
    CheckpointMode mode;
    read_checkpoint_header(path, description, mode);
    return description;
}

void throw_stopped_with_checkpoint(const RunControl& control, const std::string& where) {
    throw Interrupted(
        "stopped " + where + "; checkpoint written to " + control.checkpoint_path.string() +
        (control.resume_hint.empty() ? "" : "; continue with `" + control.resume_hint + "`"));
}

void save_sdf_parameters(BinaryWriter& out, const NeuralSdf& sdf) {
    out.tag("sdf");
    const FeatureOctree& octree = sdf.octree;
    out.value<std::int32_t>(octree.num_levels());
    for (int level = 0; level < octree.num_levels(); ++level) {
        out.value<std::uint64_t>(octree.num_corners(level));
    }
    out.value<std::uint8_t>(static_cast<std::uint8_t>(octree.feature_precision()));
    const FeatureTable& table = octree.features();
    if (table.precision() == FeaturePrecision::kFloat32) {
        out.array(table.floats(), table.size());
    } else {
        static_assert(sizeof(Imath::half) == sizeof(std::uint16_t));
        out.array(reinterpret_cast<const std::uint16_t*>(table.halves()), table.size());
    }
    out.array(sdf.decoder.params());
    out.value(sdf.origin_world_m.x());
    out.value(sdf.origin_world_m.y());
    out.value(sdf.origin_world_m.z());
}

void load_sdf_parameters(BinaryReader& in, NeuralSdf& sdf) {
    in.expect_tag("sdf");
    FeatureOctree& octree = sdf.octree;
    const auto levels = in.value<std::int32_t>("level count");
    if (levels != octree.num_levels()) {
        in.fail("level count", std::to_string(levels) + " differs from the configuration's " +
                                   std::to_string(octree.num_levels()));
    }
    for (int level = 0; level < levels; ++level) {
        const auto corners = in.value<std::uint64_t>("corner count");
        if (corners != octree.num_corners(level)) {
            in.fail("corner count", "of level " + std::to_string(level) + " is " +
                                        std::to_string(corners) + ", but the scans built " +
                                        std::to_string(octree.num_corners(level)) +
                                        " (did the data or the configuration change?)");
        }
    }
    const auto precision = in.value<std::uint8_t>("feature precision");
    if (precision != static_cast<std::uint8_t>(octree.feature_precision())) {
        in.fail("feature precision", "differs from the configuration's " +
                                         std::string(to_string(octree.feature_precision())));
    }
    FeatureTable& table = octree.features();
    if (table.precision() == FeaturePrecision::kFloat32) {
        in.array_into(table.floats(), table.size(), "features");
    } else {
        in.array_into(reinterpret_cast<std::uint16_t*>(table.halves()), table.size(), "features");
    }
    in.array_into(sdf.decoder.params().data(), sdf.decoder.num_params(), "decoder weights");
    Eigen::Vector3d origin;
    origin.x() = in.value<double>("map origin");
    origin.y() = in.value<double>("map origin");
    origin.z() = in.value<double>("map origin");
    if (origin != sdf.origin_world_m) {
        in.fail("map origin", "differs from the one the scans give (did the poses change?)");
    }
}

}  // namespace shine
