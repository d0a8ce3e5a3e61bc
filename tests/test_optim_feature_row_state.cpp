// FeatureRowState: per-row optimiser state in pages allocated on first touch, zeroed, shared
// safely by concurrent touches, released when unused, and saved/loaded exactly.
#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "shine/core/error.hpp"
#include "shine/io/binary_stream.hpp"
#include "shine/optim/feature_row_state.hpp"

namespace shine {
namespace {

constexpr std::size_t kPage = FeatureRowState::kRowsPerPage;

TEST(FeatureRowState, PagesAreAllocatedOnFirstTouchAndStartAtZero) {
    FeatureRowState state(8, /*with_anchor=*/true, /*with_master=*/false);
    state.resize(3 * kPage + 10);
    EXPECT_EQ(state.resident_pages(), 0u);
    const FeatureRowState::Row a = state.touch(static_cast<std::int32_t>(kPage + 5), 1);
    EXPECT_EQ(state.resident_pages(), 1u);
    EXPECT_EQ(a.master, nullptr);
    ASSERT_NE(a.anchor, nullptr);
    for (int l = 0; l < 8; ++l) {
        EXPECT_EQ(a.first_moment[l], 0.0f);
        EXPECT_EQ(a.second_moment[l], 0.0f);
        EXPECT_EQ(a.anchor[l], 0.0f);
    }
    EXPECT_EQ(*a.step, 0u);
    // A row's block keeps its values; a neighbour's block is distinct.
    a.first_moment[3] = 2.5f;
    *a.step = 7;
    const FeatureRowState::Row again = state.touch(static_cast<std::int32_t>(kPage + 5), 2);
    EXPECT_EQ(again.first_moment[3], 2.5f);
    EXPECT_EQ(*again.step, 7u);
    const FeatureRowState::Row next = state.touch(static_cast<std::int32_t>(kPage + 6), 2);
    EXPECT_NE(next.first_moment, again.first_moment);
    EXPECT_EQ(next.first_moment[3], 0.0f);
}

TEST(FeatureRowState, ConcurrentTouchesOfOnePageShareIt) {
    FeatureRowState state(4, false, true);
    state.resize(4 * kPage);
    tbb::parallel_for(std::size_t(0), 4 * kPage, [&](std::size_t row) {
        const FeatureRowState::Row r = state.touch(static_cast<std::int32_t>(row), 1);
        r.master[0] = static_cast<float>(row);
        ++*r.step;
    });
    EXPECT_EQ(state.resident_pages(), 4u);
    for (std::size_t row = 0; row < 4 * kPage; row += 997) {
        const FeatureRowState::Row r = state.touch(static_cast<std::int32_t>(row), 1);
        EXPECT_EQ(r.master[0], static_cast<float>(row));
        EXPECT_EQ(*r.step, 1u);
    }
}

TEST(FeatureRowState, UnusedPagesAreReleasedAndRestartFromZero) {
    FeatureRowState state(8, true, false);
    state.resize(3 * kPage);
    state.touch(0, 1).first_moment[0] = 1.0f;                                     // page 0, scan 1
    state.touch(static_cast<std::int32_t>(kPage), 3).first_moment[0] = 1.0f;      // page 1, scan 3
    state.touch(static_cast<std::int32_t>(2 * kPage), 5).first_moment[0] = 1.0f;  // page 2, scan 5
    const std::size_t full = state.memory_bytes();
    EXPECT_EQ(state.release_unused_pages(3), 1u);  // keeps pages used in scan 3 or later
    EXPECT_EQ(state.resident_pages(), 2u);
    EXPECT_LT(state.memory_bytes(), full);
    EXPECT_EQ(state.touch(0, 6).first_moment[0], 0.0f) << "a released row starts afresh";
    EXPECT_EQ(state.touch(static_cast<std::int32_t>(kPage), 6).first_moment[0], 1.0f);
}

TEST(FeatureRowState, SaveAndLoadRestoreEveryPage) {
    FeatureRowState state(8, true, true);
    state.resize(2 * kPage + 1);
    const FeatureRowState::Row r = state.touch(static_cast<std::int32_t>(2 * kPage), 4);
    r.second_moment[7] = 0.125f;
    r.anchor[1] = -3.0f;
    r.master[2] = 9.0f;
    *r.step = 11;
    *r.anchor_scan = 4;
    std::ostringstream bytes;
    BinaryWriter out(bytes);
    state.save(out);
    const auto path = std::filesystem::path(SHINE_TEST_TMP_DIR) / "row_state.bin";
    std::filesystem::create_directories(path.parent_path());
    std::ofstream(path, std::ios::binary) << bytes.str();

    FeatureRowState loaded(8, true, true);
    loaded.resize(2 * kPage + 1);
    loaded.touch(5, 1);  // replaced by the load
    BinaryReader in(path, "state");
    loaded.load(in);
    in.expect_end();
    EXPECT_EQ(loaded.resident_pages(), 1u);
    const FeatureRowState::Row s = loaded.touch(static_cast<std::int32_t>(2 * kPage), 4);
    EXPECT_EQ(s.second_moment[7], 0.125f);
    EXPECT_EQ(s.anchor[1], -3.0f);
    EXPECT_EQ(s.master[2], 9.0f);
    EXPECT_EQ(*s.step, 11u);
    EXPECT_EQ(*s.anchor_scan, 4u);
    // Released by the same rule as before the save.
    EXPECT_EQ(loaded.release_unused_pages(5), 1u);

    FeatureRowState other_layout(8, false, true);
    other_layout.resize(2 * kPage + 1);
    BinaryReader again(path, "state");
    EXPECT_THROW(other_layout.load(again), IoError);
}

}  // namespace
}  // namespace shine
