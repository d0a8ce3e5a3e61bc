#include "shine/mapper/map_budget.hpp"

#include <cstdio>
#include <string>
#include <vector>

namespace shine {

void check_map_budget(const NeuralSdf& sdf, double max_map_mb, std::size_t frame,
                      const std::filesystem::path& source) {
    if (!(max_map_mb > 0.0)) return;  // 0 = unlimited
    const std::size_t feature_bytes = sdf.octree.feature_bytes();
    const std::size_t structure_bytes = sdf.octree.structure_bytes();
    const std::size_t decoder_bytes = sdf.decoder.num_params() * sizeof(float);
    const double map_mb =
        static_cast<double>(feature_bytes + structure_bytes + decoder_bytes) / 1e6;
    if (map_mb <= max_map_mb) return;
    std::vector<char> text(source.string().size() + 1024);
    std::snprintf(
        text.data(), text.size(),
        "the map exceeds its memory budget at frame %zu ('%s'): %.2f MB (features %.2f MB + "
        "structure %.2f MB + decoder %.3f MB) > max_map_mb %.2f MB (--max-map-mb / "
        "map.max_map_mb). Stopped before training; nothing was written. To fit the budget: a "
        "larger leaf (--leaf-size-m; doubling it makes a surface map about 4x smaller), half-"
        "precision features (--half-features / map.feature_precision: float16), fewer levels "
        "(map.num_levels), or fewer scans (--last-frame, --frame-step)",
        frame, source.string().c_str(), map_mb, feature_bytes / 1e6, structure_bytes / 1e6,
        decoder_bytes / 1e6, max_map_mb);
    throw MapBudgetError(text.data());
}

}  // namespace shine
