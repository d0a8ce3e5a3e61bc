#include "shine/model/decoder_lanes.hpp"

namespace shine {

DecoderLanes::DecoderLanes(const Decoder& decoder)
    : decoder_(decoder), features_(std::size_t(decoder.input_dim()) * kDecoderLanes, 0.0f) {}

void DecoderLanes::add(const float* feature) {
    const int dim = decoder_.input_dim();
    for (int l = 0; l < dim; ++l) features_[std::size_t(l) * kDecoderLanes + count_] = feature[l];
    ++count_;
}

const float* DecoderLanes::evaluate() {
    // Lanes past size() hold earlier samples' features (or zeros): evaluated and ignored.
    if (count_ > 0) decoder_.forward_lanes(features_.data(), out_, ws_);
    count_ = 0;
    return out_;
}

}  // namespace shine
