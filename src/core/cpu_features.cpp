#include "shine/core/cpu_features.hpp"

#include <cstdlib>
#include <cstring>

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <cpuid.h>
#endif

namespace shine {
namespace {

bool cpu_has_f16c() {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
    // CPUID leaf 1, ECX: bit 27 OSXSAVE, bit 28 AVX, bit 29 F16C (Intel SDM vol. 2A, CPUID).
    // AVX registers are usable only if the OS saves their state: XCR0 bits 1 (SSE) and 2 (AVX).
    // Read directly, as clang's __builtin_cpu_supports does not know "f16c".
    unsigned eax = 0, ebx = 0, ecx = 0, edx = 0;
    if (!__get_cpuid(1, &eax, &ebx, &ecx, &edx)) return false;
    constexpr unsigned kOsxsave = 1u << 27, kAvx = 1u << 28, kF16c = 1u << 29;
    if ((ecx & (kOsxsave | kAvx | kF16c)) != (kOsxsave | kAvx | kF16c)) return false;
    unsigned xcr0_low = 0, xcr0_high = 0;
    __asm__ volatile("xgetbv" : "=a"(xcr0_low), "=d"(xcr0_high) : "c"(0));
    return (xcr0_low & 0x6u) == 0x6u;
#else
    return false;
#endif
}

bool& simd_enabled() {
    // SHINE_SIMD=off switches the fast kernels off for a whole run (side-by-side measurements).
    static bool enabled = [] {
        const char* env = std::getenv("SHINE_SIMD");
        return !(env && std::strcmp(env, "off") == 0);
    }();
    return enabled;
}

}  // namespace

bool use_avx_f16c() {
    static const bool has = cpu_has_f16c();
    return has && simd_enabled();
}

void set_simd_enabled(bool enabled) { simd_enabled() = enabled; }

}  // namespace shine
