// Mt19937_64Prefix: std::mt19937_64's outputs, bit for bit, computed only as far as they are read
// (the initial features of new map corners).
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <random>
#include <vector>

#include "shine/core/mt19937_64_prefix.hpp"
#include "shine/core/random.hpp"

using shine::Mt19937_64Prefix;

TEST(Mt19937_64Prefix, SameOutputsAsTheLibraryGeneratorPastTheHandOver) {
    // Seeds 0, 1, all bits set, and hashed ones; 400 outputs cross the hand-over at 156.
    std::vector<std::uint64_t> seeds = {0u, 1u, ~std::uint64_t(0), 5489u};
    for (std::uint64_t k = 0; k < 60; ++k) seeds.push_back(shine::mix_seed(k));
    for (const std::uint64_t seed : seeds) {
        std::mt19937_64 reference(seed);
        Mt19937_64Prefix prefix(seed);
        for (int i = 0; i < 400; ++i) {
            ASSERT_EQ(prefix(), reference()) << "seed " << seed << ", output " << i;
        }
    }
}

TEST(Mt19937_64Prefix, SameNormalDeviatesAsTheLibraryGenerator) {
    // As FeatureOctree::initial_feature draws them: 8 floats from N(0, 0.05^2) per seed, and
    // long runs, which reach the hand-over.
    for (std::uint64_t k = 0; k < 20000; ++k) {
        const std::uint64_t seed = shine::mix_seed(k ^ 0x1234u);
        std::mt19937_64 reference(seed);
        Mt19937_64Prefix prefix(seed);
        std::normal_distribution<float> a(0.0f, 0.05f), b(0.0f, 0.05f);
        const int count = k < 100 ? 200 : 8;
        for (int i = 0; i < count; ++i) {
            const float expected = a(reference);
            const float got = b(prefix);
            ASSERT_EQ(std::memcmp(&expected, &got, sizeof(float)), 0)
                << "seed " << seed << ", deviate " << i;
        }
    }
}

TEST(Mt19937_64Prefix, GeneratorsSeededSideBySideGiveTheLibraryOutputs) {
    // Four fresh generators seeded together, then read past the hand-over; and a group with one
    // generator already read, which seed_first_outputs() leaves to seed itself.
    for (std::uint64_t base = 0; base < 40; base += 4) {
        for (const bool one_read : {false, true}) {
            std::uint64_t seeds[4];
            for (int g = 0; g < 4; ++g) seeds[g] = shine::mix_seed(base + g);
            Mt19937_64Prefix r0(seeds[0]), r1(seeds[1]), r2(seeds[2]), r3(seeds[3]);
            Mt19937_64Prefix* const generators[4] = {&r0, &r1, &r2, &r3};
            std::mt19937_64 references[4] = {std::mt19937_64(seeds[0]), std::mt19937_64(seeds[1]),
                                             std::mt19937_64(seeds[2]), std::mt19937_64(seeds[3])};
            if (one_read) {
                ASSERT_EQ(r2(), references[2]());
            }
            Mt19937_64Prefix::seed_first_outputs(generators);
            for (int g = 0; g < 4; ++g) {
                for (int i = 0; i < 400; ++i) {
                    ASSERT_EQ((*generators[g])(), references[g]())
                        << "seed " << seeds[g] << ", output " << i
                        << (one_read ? ", one read" : "");
                }
            }
        }
    }
}
