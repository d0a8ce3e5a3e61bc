// std::mt19937_64's output sequence for one seed, computed only as far as it is read.
//
// The library generator seeds all 312 words of its state on construction and twists all of them
// before its first output, about 620 word updates. Each corner of a new map cell draws its initial
// feature from a generator of its own (a hash of the corner as the seed) and reads about ten
// outputs: output i < 156 depends only on the seeded words i, i + 1 and i + 156, so the first
// outputs need about 170 seeding steps and one twist each. Past output 155 (a normal deviate
// that rejected ~78 pairs in a row) this class hands over to a std::mt19937_64 that skips what
// was read. The values are the library generator's, bit for bit, and it can stand in for it as
// the engine of the standard distributions (tests/test_core_mt19937_64_prefix.cpp).
#pragma once

#include <cstdint>
#include <memory>
#include <random>

namespace shine {

class Mt19937_64Prefix {
  public:
    using result_type = std::uint64_t;
    static constexpr result_type min() { return 0; }
    static constexpr result_type max() { return ~result_type(0); }

    explicit Mt19937_64Prefix(std::uint64_t seed) { words_[0] = seed; }

    result_type operator()() {
        if (next_ >= kShift) return from_library();
        const int i = next_++;
        while (seeded_ <= i + kShift) {  // the seeding recurrence, word by word
            words_[seeded_] = seed_word(words_[seeded_ - 1], seeded_);
            ++seeded_;
        }
        const std::uint64_t y = (words_[i] & kUpperMask) | (words_[i + 1] & kLowerMask);
        std::uint64_t z = words_[i + kShift] ^ (y >> 1) ^ ((y & 1u) ? kMatrixA : 0u);
        z ^= (z >> 29) & 0x5555555555555555ull;  // tempering
        z ^= (z << 17) & 0x71d67fffeda60000ull;
        z ^= (z << 37) & 0xfff7eee000000000ull;
        z ^= z >> 43;
        return z;
    }

    /// Seeds, for N generators not read yet, the words their first output reads, all in one loop.
    /// Each generator's seeding is a chain of dependent multiplications; N independent chains
    /// side by side let the processor overlap them. The outputs are the ones each generator gives
    /// on its own. If one of them was read already, none is seeded here: each then seeds itself
    /// as it is read.
    template <int N>
    static void seed_first_outputs(Mt19937_64Prefix* const (&generators)[N]) {
        for (int g = 0; g < N; ++g) {
            if (generators[g]->seeded_ != 1 || generators[g]->next_ != 0) return;
        }
        std::uint64_t prev[N];
        for (int g = 0; g < N; ++g) prev[g] = generators[g]->words_[0];
        for (int w = 1; w <= kShift; ++w) {  // output 0 reads words 0, 1 and kShift
            for (int g = 0; g < N; ++g) {
                prev[g] = seed_word(prev[g], w);
                generators[g]->words_[w] = prev[g];
            }
        }
        for (int g = 0; g < N; ++g) generators[g]->seeded_ = kShift + 1;
    }

  private:
    static constexpr int kShift = 156;  // mt19937_64's m; n = 312
    static constexpr std::uint64_t kInitMultiplier = 6364136223846793005ull;
    static constexpr std::uint64_t kMatrixA = 0xb5026f5aa96619e9ull;
    static constexpr std::uint64_t kUpperMask = ~std::uint64_t(0) << 31;
    static constexpr std::uint64_t kLowerMask = (std::uint64_t(1) << 31) - 1;

    /// Seeded word `index` from the one before it (std::mt19937_64's initialisation).
    static std::uint64_t seed_word(std::uint64_t prev, int index) {
        return kInitMultiplier * (prev ^ (prev >> 62)) + std::uint64_t(index);
    }

    result_type from_library() {
        if (!library_) {
            library_ = std::make_unique<std::mt19937_64>(words_[0]);  // the seed
            library_->discard(kShift);
        }
        return (*library_)();
    }

    int next_ = 0;    ///< outputs read
    int seeded_ = 1;  ///< words_[0, seeded_) hold the seeded state; words_[0] is the seed
    std::uint64_t words_[2 * kShift];
    std::unique_ptr<std::mt19937_64> library_;
};

}  // namespace shine
