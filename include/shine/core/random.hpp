// Small, fast, seedable random numbers for kernels (PCG32). Seeded per task from (seed, ids) so
// results do not depend on thread scheduling.
#pragma once

#include <cstdint>

namespace shine {

/// splitmix64 step: turns any 64-bit value into a well-mixed one (for deriving stream seeds).
inline std::uint64_t mix_seed(std::uint64_t x) {
    x += 0x9E3779B97F4A7C15ull;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
}

/// Seed of a sub-stream identified by (seed, a, b).
inline std::uint64_t stream_seed(std::uint64_t seed, std::uint64_t a, std::uint64_t b = 0) {
    return mix_seed(mix_seed(mix_seed(seed) ^ a) ^ b);
}

/// PCG32 (O'Neill's permuted congruential generator, XSH-RR output).
class Pcg32 {
  public:
    explicit Pcg32(std::uint64_t seed) : state_(0), inc_((mix_seed(seed) << 1u) | 1u) {
        next();
        state_ += mix_seed(seed ^ 0xDA3E39CB94B95BDBull);
        next();
    }
    std::uint32_t next() {
        const std::uint64_t old = state_;
        state_ = old * 6364136223846793005ull + inc_;
        const auto xorshifted = static_cast<std::uint32_t>(((old >> 18u) ^ old) >> 27u);
        const auto rot = static_cast<std::uint32_t>(old >> 59u);
        return (xorshifted >> rot) | (xorshifted << ((32u - rot) & 31u));
    }
    /// Uniform in [0, 1).
    float uniform() { return static_cast<float>(next() >> 8) * (1.0f / 16777216.0f); }
    /// Uniform in [lo, hi).
    float uniform(float lo, float hi) { return lo + (hi - lo) * uniform(); }
    /// Uniform integer in [0, n) (n > 0), by multiply-shift (bias < n / 2^32).
    std::uint32_t below(std::uint32_t n) {
        return static_cast<std::uint32_t>((static_cast<std::uint64_t>(next()) * n) >> 32);
    }
    /// Uniform 64-bit index in [0, n) for n up to 2^64.
    std::uint64_t below64(std::uint64_t n) {
        const std::uint64_t r = (static_cast<std::uint64_t>(next()) << 32) | next();
        return static_cast<std::uint64_t>((static_cast<unsigned __int128>(r) * n) >> 64);
    }

  private:
    std::uint64_t state_;
    std::uint64_t inc_;
};

}  // namespace shine
