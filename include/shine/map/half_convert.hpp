// Conversion of runs of features between float16 (Imath::half) and float.
//
// Imath converts one value at a time: float16 -> float through a 256 KiB table, float -> float16
// with integer arithmetic, unless the whole program is compiled for F16C. Training converts every
// feature row it reads and every row Adam writes back, so these run 8 values per instruction with
// F16C where the CPU has it (core/cpu_features.hpp). Both conversions are exact IEEE operations
// (float16 -> float is exact; float -> float16 rounds to nearest, ties to even, with subnormals,
// overflow to infinity), so the results equal Imath's bit for bit for every value that is not a
// NaN (a NaN stays a NaN; its payload bits may differ).
#pragma once

#include <Imath/half.h>

#include <cstddef>

namespace shine {

/// out[i] = float(in[i]) for i < count.
void halves_to_floats(const Imath::half* in, float* out, std::size_t count);

/// out[i] = half(in[i]) (round to nearest even) for i < count.
void floats_to_halves(const float* in, Imath::half* out, std::size_t count);

}  // namespace shine
