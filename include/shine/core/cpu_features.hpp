// Which optional x86-64 instructions the kernels may use, decided once at run time.
//
// The default build targets any x86-64 CPU (SSE2). A few kernels have a second version compiled
// for AVX and F16C (function target attributes, no FMA, so the same IEEE operations in the same
// order as their plain versions: results are bit for bit the same, only faster). They call
// use_avx_f16c() to pick one; tests switch the fast versions off to compare both.
#pragma once

namespace shine {

/// True when the CPU supports AVX and F16C (every x86-64 CPU since 2013) and the fast kernels are
/// not switched off; false on other architectures.
bool use_avx_f16c();

/// Switches the AVX/F16C kernels off (false) or back on where the CPU has them (true), for tests
/// and side-by-side measurements. Not thread-safe against running kernels.
void set_simd_enabled(bool enabled);

}  // namespace shine
