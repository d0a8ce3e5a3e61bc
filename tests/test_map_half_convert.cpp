// The float16 <-> float run conversions (map/half_convert.hpp) against Imath's one-value
// conversions, bit for bit, with the fast (F16C) kernels on and off.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

#include "shine/core/cpu_features.hpp"
#include "shine/map/half_convert.hpp"

using namespace shine;

namespace {

std::uint32_t float_bits(float f) {
    std::uint32_t u;
    std::memcpy(&u, &f, sizeof u);
    return u;
}

float bits_float(std::uint32_t u) {
    float f;
    std::memcpy(&f, &u, sizeof f);
    return f;
}

/// Floats that exercise every rounding case of float -> float16: every exponent with mantissas
/// at, just below and just above the half-way points between float16 values, subnormal halves,
/// overflow, zeros and infinities, and random bit patterns; NaNs are left out (their payloads
/// are not specified).
std::vector<float> float_cases() {
    std::vector<float> cases;
    for (std::uint32_t sign = 0; sign < 2; ++sign) {
        for (std::uint32_t exponent = 0; exponent < 255; ++exponent) {
            for (std::uint32_t high = 0; high < 1024; high += 37) {
                const std::uint32_t base = (sign << 31) | (exponent << 23) | (high << 13);
                for (std::uint32_t low : {0u, 1u, 0xfffu, 0x1000u, 0x1001u, 0x1fffu}) {
                    cases.push_back(bits_float(base | low));
                }
            }
        }
        cases.push_back(bits_float((sign << 31) | 0x7f800000u));  // infinity
    }
    std::mt19937 rng(3);
    for (int i = 0; i < 200000; ++i) {
        const float f = bits_float(static_cast<std::uint32_t>(rng()));
        if (!std::isnan(f)) cases.push_back(f);
    }
    return cases;
}

class HalfConvert : public ::testing::TestWithParam<bool> {
  protected:
    void SetUp() override { set_simd_enabled(GetParam()); }
    void TearDown() override { set_simd_enabled(true); }
};

}  // namespace

TEST_P(HalfConvert, EveryHalfToFloatEqualsImath) {
    std::vector<Imath::half> halves(65536);
    for (std::uint32_t i = 0; i < 65536; ++i) halves[i].setBits(static_cast<std::uint16_t>(i));
    // Odd lengths and offsets: the vector loop and the scalar tail.
    for (std::size_t offset : {0, 3}) {
        std::vector<float> out(halves.size() - offset, -1.0f);
        halves_to_floats(halves.data() + offset, out.data(), out.size());
        for (std::size_t i = 0; i < out.size(); ++i) {
            const float reference = static_cast<float>(halves[i + offset]);
            if (std::isnan(reference)) {
                EXPECT_TRUE(std::isnan(out[i])) << "half bits " << i + offset;
            } else {
                ASSERT_EQ(float_bits(out[i]), float_bits(reference)) << "half bits " << i + offset;
            }
        }
    }
}

TEST_P(HalfConvert, FloatToHalfRoundsAsImath) {
    const std::vector<float> cases = float_cases();
    for (std::size_t offset : {0, 5}) {
        std::vector<Imath::half> out(cases.size() - offset);
        floats_to_halves(cases.data() + offset, out.data(), out.size());
        for (std::size_t i = 0; i < out.size(); ++i) {
            const Imath::half reference(cases[i + offset]);
            ASSERT_EQ(out[i].bits(), reference.bits())
                << "float " << cases[i + offset] << " (bits " << std::hex
                << float_bits(cases[i + offset]) << ")";
        }
    }
}

TEST_P(HalfConvert, NaNStaysNaN) {
    const float nan = std::nanf("");
    Imath::half h[9];
    float back[9];
    const float in[9] = {nan, nan, nan, nan, nan, nan, nan, nan, nan};
    floats_to_halves(in, h, 9);
    halves_to_floats(h, back, 9);
    for (int i = 0; i < 9; ++i) EXPECT_TRUE(std::isnan(back[i]));
}

INSTANTIATE_TEST_SUITE_P(FastAndPlain, HalfConvert, ::testing::Values(true, false),
                         [](const auto& info) { return info.param ? "fast" : "plain"; });
