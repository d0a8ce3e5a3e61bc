// Portable, seedable random numbers for the simulator (private header).
//
// std::mt19937_64 is fully specified by the standard; the conversions to uniform and normal
// numbers are done here (not by std::*_distribution, whose algorithms differ between standard
// libraries), so a seed gives the same street and the same noise everywhere.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

namespace shine::sim::random_internal {

/// SplitMix64 finaliser: a well-mixed 64-bit hash, used to derive independent seeds.
inline std::uint64_t splitmix64(std::uint64_t x) {
    x += 0x9E3779B97F4A7C15ULL;
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
    return x ^ (x >> 31);
}

/// Seed of the independent stream `stream` derived from `seed`.
inline std::uint64_t derive_seed(std::uint64_t seed, std::uint64_t stream) {
    return splitmix64(splitmix64(seed) ^ splitmix64(stream + 0x632BE59BD9B4E019ULL));
}

/// Uniform double in [0, 1) from 64 random bits.
inline double unit_from_bits(std::uint64_t bits) {
    return static_cast<double>(bits >> 11) * 0x1.0p-53;
}

/// Standard normal number from two 64-bit words (Box-Muller).
inline double normal_from_bits(std::uint64_t bits_a, std::uint64_t bits_b) {
    const double u1 = 1.0 - unit_from_bits(bits_a);  // (0, 1]: log is finite
    const double u2 = unit_from_bits(bits_b);
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

/// A small stateful generator for procedural layouts.
class Rng {
  public:
    explicit Rng(std::uint64_t seed) : engine_(seed) {}
    /// Uniform in [lo, hi).
    double uniform(double lo, double hi) { return lo + (hi - lo) * unit_from_bits(engine_()); }
    /// Uniform integer in [lo, hi].
    int uniform_int(int lo, int hi) {
        return lo + static_cast<int>(unit_from_bits(engine_()) * (hi - lo + 1));
    }
    /// True with probability p.
    bool chance(double p) { return unit_from_bits(engine_()) < p; }

  private:
    std::mt19937_64 engine_;
};

}  // namespace shine::sim::random_internal
