// Interpolation weights of a cell's 8 corners, and their spatial gradient.
//
// Per axis the upper corner gets the weight s(t) and the lower one 1 - s(t), with t the position in
// the cell; corner c uses bit 0/1/2 of c for the x/y/z side, as in LevelCorners.
//   - smoothstep, s(t) = 3t^2 - 2t^3: C1-continuous across cells, so the SDF's gradient, which the
//     Eikonal term constrains, has no jumps at cell faces; but ds/dt = 0 at t = 0 and 1, so at a
//     cell corner no level's features can tilt the SDF, and since the levels' grids are nested,
//     at a level-(H-1) corner no level can: the learned surface gets flat spots on a lattice.
//   - linear, s(t) = t (trilinear): gradients jump at cell faces but never vanish.
// Measured on the shared real sequence (docs/heldout.md), linear weights score better on held-out
// scans; smoothstep stays the default of the paper's reproduction and of existing maps.
#pragma once

#include "shine/map/feature_octree.hpp"

namespace shine {

/// s(t) = 3t^2 - 2t^3.
inline float smoothstep(float t) { return t * t * (3.0f - 2.0f * t); }
/// ds/dt = 6t - 6t^2.
inline float smoothstep_derivative(float t) { return 6.0f * t * (1.0f - t); }

/// s(t) of `kind`.
inline float interpolation_weight(Interpolation kind, float t) {
    return kind == Interpolation::kLinear ? t : smoothstep(t);
}
/// ds/dt of `kind`.
inline float interpolation_derivative(Interpolation kind, float t) {
    return kind == Interpolation::kLinear ? 1.0f : smoothstep_derivative(t);
}

/// Weights of the 8 corners for cell coordinates t in [0,1]^3.
inline void corner_weights(const float t[3], float weights[8],
                           Interpolation kind = Interpolation::kSmoothstep) {
    float hi[3], lo[3];
    for (int a = 0; a < 3; ++a) {
        hi[a] = interpolation_weight(kind, t[a]);
        lo[a] = 1.0f - hi[a];
    }
    for (int c = 0; c < 8; ++c) {
        weights[c] =
            ((c & 1) ? hi[0] : lo[0]) * ((c & 2) ? hi[1] : lo[1]) * ((c & 4) ? hi[2] : lo[2]);
    }
}

/// Weights and their gradient with respect to the query position in metres (cell_size_m: the
/// cell's edge length, since t = x / cell_size_m - floor).
inline void corner_weights_and_gradients(const float t[3], float cell_size_m, float weights[8],
                                         float gradients_per_m[8][3],
                                         Interpolation kind = Interpolation::kSmoothstep) {
    float hi[3], lo[3], dhi[3];
    const float inv = 1.0f / cell_size_m;
    for (int a = 0; a < 3; ++a) {
        hi[a] = interpolation_weight(kind, t[a]);
        lo[a] = 1.0f - hi[a];
        dhi[a] = interpolation_derivative(kind, t[a]) * inv;
    }
    for (int c = 0; c < 8; ++c) {
        const float wx = (c & 1) ? hi[0] : lo[0];
        const float wy = (c & 2) ? hi[1] : lo[1];
        const float wz = (c & 4) ? hi[2] : lo[2];
        const float dx = (c & 1) ? dhi[0] : -dhi[0];
        const float dy = (c & 2) ? dhi[1] : -dhi[1];
        const float dz = (c & 4) ? dhi[2] : -dhi[2];
        weights[c] = wx * wy * wz;
        gradients_per_m[c][0] = dx * wy * wz;
        gradients_per_m[c][1] = wx * dy * wz;
        gradients_per_m[c][2] = wx * wy * dz;
    }
}

}  // namespace shine
