// Loss terms on the decoded SDF (paper Eqs. (1)-(3)).
#pragma once

#include <cmath>

namespace shine {

/// A loss value and its derivative with respect to the predicted SDF f.
struct LossAndGradient {
    float loss;
    float gradient;
};

/// Logistic sigmoid.
inline float sigmoid(float z) { return 1.0f / (1.0f + std::exp(-z)); }

/// Eq. (1): binary cross entropy between o = sigmoid(f/sigma) and the label l = sigmoid(d/sigma),
/// d the projective signed distance of the sample (positive in free space). Written as
/// softplus(z) - l*z with z = f/sigma, which is exact and never takes log(0).
inline LossAndGradient sigmoid_bce(float sdf_pred_m, float sdf_label_m, float sigma_m) {
    const float z = sdf_pred_m / sigma_m;
    const float label = sigmoid(sdf_label_m / sigma_m);
    const float softplus = z > 0.0f ? z + std::log1p(std::exp(-z)) : std::log1p(std::exp(z));
    return {softplus - label * z, (sigmoid(z) - label) / sigma_m};
}

/// Eq. (3): Eikonal term (|g| - 1)^2 of the SDF gradient g; writes de/dg into grad_out.
inline float eikonal_loss(const float g[3], float grad_out[3]) {
    const float norm = std::sqrt(g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
    const float residual = norm - 1.0f;
    const float scale = norm > 1e-12f ? 2.0f * residual / norm : 0.0f;
    for (int a = 0; a < 3; ++a) grad_out[a] = scale * g[a];
    return residual * residual;
}

}  // namespace shine
