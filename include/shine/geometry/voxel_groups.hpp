// Points grouped by voxel: a list of points in which each voxel's points form one run, described
// by the index where each run starts (preprocess_scan() with VoxelPoints::kAll). An empty list of
// starts means every point is a run of its own.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

namespace shine {

/// Calls f(i, run) for the points i = 0 .. count - 1 in order, `run` being point i's run: its
/// index in `voxel_begin`, or i when `voxel_begin` is empty (every point a run of its own).
template <class F>
void for_each_point_run(std::size_t count, const std::vector<std::uint32_t>& voxel_begin,
                        const F& f) {
    std::size_t run = 0;
    for (std::size_t i = 0; i < count; ++i) {
        if (voxel_begin.empty()) {
            run = i;
        } else {
            while (run + 1 < voxel_begin.size() && voxel_begin[run + 1] <= i) ++run;
        }
        f(i, run);
    }
}

/// Keeps the points for which keep(i, run) is true, in order (`run` is point i's run: its index
/// in `voxel_begin`, or i when ungrouped), and rewrites `voxel_begin` for what is kept: a run
/// keeps its place, loses its removed points, and disappears when none is left. An empty
/// `voxel_begin` stays empty. Each of `per_point` (null, empty, or one value per point: ray
/// origins, intensities, ...) keeps the values of the kept points. Returns the number of points
/// removed.
template <class Keep, class... Values>
std::size_t filter_voxel_grouped(std::vector<Eigen::Vector3f>& points,
                                 std::vector<std::uint32_t>& voxel_begin, const Keep& keep,
                                 std::vector<Values>*... per_point) {
    [[maybe_unused]] const auto with_values = [&](const auto* values) {
        return values != nullptr && values->size() == points.size();
    };
    [[maybe_unused]] const bool with[sizeof...(Values) + 1] = {with_values(per_point)..., false};
    const bool grouped = !voxel_begin.empty();
    std::vector<std::uint32_t> begins;
    if (grouped) begins.reserve(voxel_begin.size());
    constexpr std::size_t kNoRun = std::numeric_limits<std::size_t>::max();
    std::size_t kept = 0;
    std::size_t last_opened = kNoRun;  // the last run that has a kept point
    for_each_point_run(points.size(), voxel_begin, [&](std::size_t i, std::size_t run) {
        if (!keep(i, run)) return;
        if (grouped && run != last_opened) {
            begins.push_back(static_cast<std::uint32_t>(kept));
            last_opened = run;
        }
        [[maybe_unused]] std::size_t v = 0;
        ((with[v++] ? void((*per_point)[kept] = (*per_point)[i]) : void()), ...);
        points[kept++] = points[i];
    });
    const std::size_t removed = points.size() - kept;
    [[maybe_unused]] std::size_t v = 0;
    ((with[v++] ? per_point->resize(kept) : void()), ...);
    points.resize(kept);
    if (grouped) voxel_begin = std::move(begins);
    return removed;
}

}  // namespace shine
