// TrivialArray: an exactly sized array that grows in place (the feature table's storage).
#include <gtest/gtest.h>

#include <cinttypes>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "shine/core/trivial_array.hpp"

using shine::TrivialArray;

TEST(TrivialArray, GrowingKeepsTheValuesAndFillsTheNewOnes) {
    TrivialArray<std::int32_t> a;
    EXPECT_TRUE(a.empty());
    EXPECT_EQ(a.data(), nullptr);
    a.resize(3, -1);
    ASSERT_EQ(a.size(), 3u);
    EXPECT_EQ(a.bytes(), 3 * sizeof(std::int32_t));
    a[1] = 7;
    // Grow in steps, as a map does scan by scan, past sizes glibc serves with mmap.
    std::size_t n = 3;
    std::int32_t previous_fill = -1;
    while (n < (std::size_t(48) << 20) / sizeof(std::int32_t)) {
        const std::size_t old = n;
        n += n / 3 + 1000;
        a.resize(n, static_cast<std::int32_t>(old));
        ASSERT_EQ(a[1], 7);
        ASSERT_EQ(a[old - 1], previous_fill);  // the last value of the previous size survives
        ASSERT_EQ(a[old], static_cast<std::int32_t>(old));
        ASSERT_EQ(a[n - 1], static_cast<std::int32_t>(old));
        previous_fill = static_cast<std::int32_t>(old);
    }
    EXPECT_EQ(a[0], -1);
    EXPECT_EQ(a[2], -1);
    // Shrinking keeps the front; growing again fills with the new value, not stale ones.
    a.resize(2);
    a.resize(4, 9);
    EXPECT_EQ(a[1], 7);
    EXPECT_EQ(a[2], 9);
    EXPECT_EQ(a[3], 9);
    a.resize(0);
    EXPECT_TRUE(a.empty());
    EXPECT_EQ(a.bytes(), 0u);
}

TEST(TrivialArray, CopiesAreIndependentAndMovesTakeTheBlock) {
    const std::vector<float> source = {1.5f, -2.0f, 3.25f};
    TrivialArray<float> a(source.begin(), source.end());
    TrivialArray<float> b = a;
    b[0] = 10.0f;
    EXPECT_EQ(a[0], 1.5f);
    EXPECT_EQ(std::vector<float>(b.begin(), b.end()), (std::vector<float>{10.0f, -2.0f, 3.25f}));
    const float* block = a.data();
    TrivialArray<float> c = std::move(a);
    EXPECT_EQ(c.data(), block);
    EXPECT_TRUE(a.empty());  // NOLINT(bugprone-use-after-move): moved-from is empty
    b = c;
    EXPECT_EQ(b[0], 1.5f);
    EXPECT_NE(b.data(), c.data());
    // Converting construction (float -> double here; the table converts float <-> half).
    const TrivialArray<double> d(c.begin(), c.end());
    EXPECT_EQ(d[2], 3.25);
}

#if defined(__linux__)
namespace {
/// Number of mappings in /proc/self/maps that overlap [begin, end).
int mappings_overlapping(const void* begin, const void* end) {
    std::ifstream maps("/proc/self/maps");
    std::string line;
    int count = 0;
    const auto lo = reinterpret_cast<std::uintptr_t>(begin);
    const auto hi = reinterpret_cast<std::uintptr_t>(end);
    while (std::getline(maps, line)) {
        std::uintptr_t from = 0, to = 0;
        if (std::sscanf(line.c_str(), "%" SCNxPTR "-%" SCNxPTR, &from, &to) != 2) continue;
        if (from < hi && lo < to) ++count;
    }
    return count;
}
}  // namespace

TEST(TrivialArray, ALargeBlockStaysOneMappingSoThatItGrowsWithoutACopy) {
    // glibc grows a large block with mremap(), which moves only whole mappings: anything that
    // splits the block's mapping (an madvise() on part of it did) turns every later growth into
    // a copy of the whole array, as for a city-scale feature table on every scan.
    TrivialArray<float> a;
    std::size_t n = std::size_t(8) << 20;  // 32 MiB, served by mmap
    for (int step = 0; step < 8; ++step) {
        a.resize(n, 1.0f);
        ASSERT_EQ(mappings_overlapping(a.data(), a.data() + a.size()), 1)
            << "after " << n << " values";
        n += n / 16;
    }
}
#endif
