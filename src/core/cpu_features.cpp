#include "shine/core/cpu_features.hpp"

#include <cstdlib>
#include <cstring>

namespace shine {
namespace {

bool cpu_has_f16c() {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
    __builtin_cpu_init();
    return __builtin_cpu_supports("avx") && __builtin_cpu_supports("f16c");
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
