// Smoothstep-trilinear interpolation weights of a cell's 8 corners, and their spatial gradient.
//
// Per axis the weight of the upper corner is s(t) = 3t^2 - 2t^3 (C1-continuous across cells, so the
// SDF's gradient, which the Eikonal term constrains, has no jumps at cell faces); the lower corner
// gets 1 - s(t). Corner c uses bit 0/1/2 of c for the x/y/z side, as in LevelCorners.
#pragma once

namespace shine {

/// s(t) = 3t^2 - 2t^3.
inline float smoothstep(float t) { return t * t * (3.0f - 2.0f * t); }
/// ds/dt = 6t - 6t^2.
inline float smoothstep_derivative(float t) { return 6.0f * t * (1.0f - t); }

/// Weights of the 8 corners for cell coordinates t in [0,1]^3.
inline void corner_weights(const float t[3], float weights[8]) {
    float hi[3], lo[3];
    for (int a = 0; a < 3; ++a) {
        hi[a] = smoothstep(t[a]);
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
                                         float gradients_per_m[8][3]) {
    float hi[3], lo[3], dhi[3];
    const float inv = 1.0f / cell_size_m;
    for (int a = 0; a < 3; ++a) {
        hi[a] = smoothstep(t[a]);
        lo[a] = 1.0f - hi[a];
        dhi[a] = smoothstep_derivative(t[a]) * inv;
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
