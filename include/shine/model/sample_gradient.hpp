// Loss of one training sample and its gradient with respect to the corner features and the
// decoder weights (paper Eq. (4): L_bce + lambda_e * L_eikonal). The trainer calls this per sample;
// tests check it against finite differences.
#pragma once

#include "shine/model/feature_encoding.hpp"
#include "shine/model/neural_sdf.hpp"
#include "shine/sampling/ray_sampler.hpp"

namespace shine {

/// Weights of the loss terms of one sample.
struct SampleLossConfig {
    float sigma_m = 0.05f;        ///< sigmoid scale of Eq. (1)
    float eikonal_weight = 0.1f;  ///< lambda_e; applied to surface samples only
};

/// Loss and feature gradient of one sample. The gradient of corner k's feature row
/// encoded.rows[k] is coefficients[k] * h: both loss terms reach a feature only along h = df/dF.
struct SampleGradient {
    float bce = 0.0f;
    float eikonal = 0.0f;  ///< unweighted (|grad f| - 1)^2, 0 for free-space samples
    float sdf_m = 0.0f;    ///< the prediction f
    float h[kMaxFeatureDim];
    float coefficients[8 * kMaxLevels];
};

/// Encodes the sample into `encoded` and, if it is inside the map, fills `out` and adds the
/// decoder's parameter gradient to `decoder_grads` (when not null). Returns false (and touches
/// nothing else) when no level covers the sample.
bool sample_loss_gradient(const NeuralSdf& sdf, CellLookup& lookup, DecoderWorkspace& ws,
                          const RaySample& sample, const SampleLossConfig& config,
                          EncodedPoint& encoded, SampleGradient& out, float* decoder_grads);

}  // namespace shine
