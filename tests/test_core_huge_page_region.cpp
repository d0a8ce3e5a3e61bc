#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <utility>

#include "shine/core/huge_page_region.hpp"

namespace shine {
namespace {

bool all_zero(const unsigned char* bytes, std::size_t count) {
    for (std::size_t i = 0; i < count; ++i) {
        if (bytes[i] != 0) return false;
    }
    return true;
}

TEST(HugePageRegion, IsAlignedRoundedUpAndZero) {
    const HugePageRegion region(3 * 1000 * 1000);
    ASSERT_NE(region.data(), nullptr);
    EXPECT_EQ(reinterpret_cast<std::uintptr_t>(region.data()) % HugePageRegion::kHugePageBytes, 0u);
    EXPECT_EQ(region.bytes(), 2 * HugePageRegion::kHugePageBytes);
    EXPECT_TRUE(all_zero(static_cast<const unsigned char*>(region.data()), region.bytes()));
}

TEST(HugePageRegion, DiscardedMemoryReadsAsZerosAndTheRestIsKept) {
    HugePageRegion region(HugePageRegion::kHugePageBytes);
    auto* bytes = static_cast<unsigned char*>(region.data());
    std::memset(bytes, 0xab, region.bytes());
    constexpr std::size_t kPage = 4096;
    region.discard(4 * kPage, 8 * kPage);
    EXPECT_TRUE(all_zero(bytes + 4 * kPage, 8 * kPage));
    EXPECT_EQ(bytes[4 * kPage - 1], 0xab);
    EXPECT_EQ(bytes[12 * kPage], 0xab);
    EXPECT_EQ(bytes[region.bytes() - 1], 0xab);
    bytes[5 * kPage] = 7;  // discarded memory is usable again
    EXPECT_EQ(bytes[5 * kPage], 7);
}

TEST(HugePageRegion, MovesOwnership) {
    HugePageRegion a(1);
    void* data = a.data();
    static_cast<unsigned char*>(data)[0] = 42;
    HugePageRegion b(std::move(a));
    EXPECT_EQ(a.data(), nullptr);
    EXPECT_EQ(a.bytes(), 0u);
    EXPECT_EQ(b.data(), data);
    HugePageRegion c;
    c = std::move(b);
    EXPECT_EQ(c.data(), data);
    EXPECT_EQ(static_cast<unsigned char*>(c.data())[0], 42);
    EXPECT_EQ(HugePageRegion(0).data(), nullptr);
}

}  // namespace
}  // namespace shine
