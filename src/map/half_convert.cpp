#include "shine/map/half_convert.hpp"

#include "shine/core/cpu_features.hpp"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define SHINE_HAVE_F16C_KERNELS 1
#endif

namespace shine {
namespace {

#if defined(SHINE_HAVE_F16C_KERNELS)
__attribute__((target("avx,f16c"))) void halves_to_floats_f16c(const Imath::half* in, float* out,
                                                               std::size_t count) {
    std::size_t i = 0;
    for (; i + 8 <= count; i += 8) {
        const __m128i h = _mm_loadu_si128(reinterpret_cast<const __m128i*>(in + i));
        _mm256_storeu_ps(out + i, _mm256_cvtph_ps(h));
    }
    for (; i < count; ++i) out[i] = static_cast<float>(in[i]);
}

__attribute__((target("avx,f16c"))) void floats_to_halves_f16c(const float* in, Imath::half* out,
                                                               std::size_t count) {
    std::size_t i = 0;
    for (; i + 8 <= count; i += 8) {
        const __m128i h = _mm256_cvtps_ph(_mm256_loadu_ps(in + i), _MM_FROUND_TO_NEAREST_INT);
        _mm_storeu_si128(reinterpret_cast<__m128i*>(out + i), h);
    }
    for (; i < count; ++i) out[i] = Imath::half(in[i]);
}
#endif

}  // namespace

void halves_to_floats(const Imath::half* in, float* out, std::size_t count) {
#if defined(SHINE_HAVE_F16C_KERNELS)
    if (use_avx_f16c()) return halves_to_floats_f16c(in, out, count);
#endif
    for (std::size_t i = 0; i < count; ++i) out[i] = static_cast<float>(in[i]);
}

void floats_to_halves(const float* in, Imath::half* out, std::size_t count) {
#if defined(SHINE_HAVE_F16C_KERNELS)
    if (use_avx_f16c()) return floats_to_halves_f16c(in, out, count);
#endif
    for (std::size_t i = 0; i < count; ++i) out[i] = Imath::half(in[i]);
}

}  // namespace shine
