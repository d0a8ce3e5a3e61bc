#include "shine/model/sample_gradient.hpp"

#include "shine/model/sdf_loss.hpp"

namespace shine {

bool sample_loss_gradient(const NeuralSdf& sdf, CellLookup& lookup, DecoderWorkspace& ws,
                          const RaySample& sample, const SampleLossConfig& config,
                          EncodedPoint& encoded, SampleGradient& out, float* decoder_grads) {
    const int dim = sdf.octree.feature_dim();
    const FeatureTableView features = sdf.octree.features().data();
    const bool eikonal = config.eikonal_weight > 0.0f && sample.kind == SampleKind::kSurface;
    encode_point(lookup, sdf.octree, sample.point_map, eikonal, encoded);
    if (!encoded.valid()) return false;

    float feature[kMaxFeatureDim];
    gather_feature(encoded, features, dim, feature);
    out.sdf_m = sdf.decoder.forward(feature, ws);
    sdf.decoder.input_gradient(ws, out.h);

    // Eq. (1): dL_bce/dtheta_c = (w_c * dL/df) * h.
    const LossAndGradient bce = sigmoid_bce(out.sdf_m, sample.sdf_label_m, config.sigma_m);
    out.bce = bce.loss;
    out.eikonal = 0.0f;
    if (decoder_grads) sdf.decoder.accumulate_param_gradient(ws, bce.gradient, decoder_grads);
    for (int k = 0; k < encoded.num_corners; ++k)
        out.coefficients[k] = encoded.weights[k] * bce.gradient;
    if (!eikonal) return true;

    // Eq. (3): g = J^T h is the SDF's spatial gradient (J = dF/dx). For e = (|g| - 1)^2,
    // de/dtheta_c = (dw_c/dx . de/dg) * h, and de/dh = J de/dg feeds the decoder's weights.
    float jacobian[3 * kMaxFeatureDim];
    feature_jacobian(encoded, features, dim, jacobian);
    float g[3] = {0.0f, 0.0f, 0.0f};
    for (int l = 0; l < dim; ++l) {
        for (int a = 0; a < 3; ++a) g[a] += jacobian[l * 3 + a] * out.h[l];
    }
    float de_dg[3];
    out.eikonal = eikonal_loss(g, de_dg);
    for (int a = 0; a < 3; ++a) de_dg[a] *= config.eikonal_weight;
    for (int k = 0; k < encoded.num_corners; ++k) {
        const float* dw = encoded.weight_gradients_per_m[k];
        out.coefficients[k] += dw[0] * de_dg[0] + dw[1] * de_dg[1] + dw[2] * de_dg[2];
    }
    if (decoder_grads) {
        float de_dh[kMaxFeatureDim];
        for (int l = 0; l < dim; ++l) {
            de_dh[l] = jacobian[l * 3 + 0] * de_dg[0] + jacobian[l * 3 + 1] * de_dg[1] +
                       jacobian[l * 3 + 2] * de_dg[2];
        }
        sdf.decoder.accumulate_input_gradient_param_gradient(ws, de_dh, decoder_grads);
    }
    return true;
}

}  // namespace shine
