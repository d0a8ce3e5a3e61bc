// Losses and feature gradients of a batch of training samples: the batched form of
// sample_gradient.hpp (paper Eq. (4): L_bce + lambda_e * L_eikonal), which stays the per-sample
// reference the tests compare against.
//
// Each sample's corners are looked up once (encode_point); the decoder then runs on all samples
// that fall inside the map as matrix products (batched_decoder.hpp), and the per-sample loss
// terms and corner coefficients follow. As in sample_gradient.hpp, the gradient of the loss of
// valid sample b on its corner k's feature row is coefficient(b, k) * h_b, h_b = df/dF.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "shine/model/batched_decoder.hpp"
#include "shine/model/feature_encoding.hpp"
#include "shine/model/neural_sdf.hpp"
#include "shine/model/sample_gradient.hpp"
#include "shine/sampling/ray_sampler.hpp"

namespace shine {

/// Per valid sample (one that some level covers): corner rows, coefficients and h; and the sums
/// of the loss terms.
struct BatchGradient {
    int corner_stride = 0;              ///< 8 x levels: slots per sample in rows/coefficients
    std::vector<std::uint32_t> sample;  ///< index of each valid sample in the input
    std::vector<std::uint8_t> corners;  ///< corners of each valid sample (8 x contributing levels)
    std::vector<std::int32_t> rows;     ///< feature rows, corner_stride per valid sample
    std::vector<float> coefficients;    ///< dL/dtheta_row = coefficient * h, corner_stride each
    std::vector<float> sdf_m;           ///< the prediction f per valid sample
    double bce_sum = 0.0;               ///< sum of the valid samples' BCE
    double eikonal_sum = 0.0;           ///< sum of the (unweighted) Eikonal terms
    DecoderBatch decoder;               ///< decoder.input_gradient column b = h_b

    std::size_t num_valid() const { return sample.size(); }
    const float* h(std::size_t b) const {
        return decoder.input_gradient.col(Eigen::Index(b)).data();
    }

    // Scratch of the Eikonal term, per valid sample.
    std::vector<float> weight_gradients_per_m;  ///< 3 x corner_stride
    std::vector<float> jacobian;                ///< dF/dx, axis-major 3 x L (surface samples)
    std::vector<std::uint8_t> eikonal;          ///< 1 when the sample gets the Eikonal term
    Eigen::RowVectorXf grad_output;             ///< dL/df per valid sample
    Eigen::MatrixXf grad_input_gradient;        ///< dL_eikonal/dh per valid sample, L x B
};

/// Losses and gradients of samples[0, count) with the weights of `config` (see
/// sample_loss_gradient, which this equals up to float rounding): fills `out` and, when
/// `decoder_grads` is not null, adds the decoder's parameter gradient of the summed loss to it.
void batch_loss_gradient(const NeuralSdf& sdf, CellLookup& lookup, const RaySample* samples,
                         std::size_t count, const SampleLossConfig& config, BatchGradient& out,
                         float* decoder_grads);

}  // namespace shine
