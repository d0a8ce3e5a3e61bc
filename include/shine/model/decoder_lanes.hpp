// Evaluating the decoder on many points (bake, map queries) kDecoderLanes at a time with
// Decoder::forward_lanes(): samples are queued until the lanes are full, then evaluated together.
// Each lane does forward()'s operations in the same order, so the values are bit for bit those of
// forward() one sample at a time (tests/test_model_decoder_lanes.cpp).
#pragma once

#include <vector>

#include "shine/model/decoder.hpp"

namespace shine {

/// Queues samples' features and evaluates them kDecoderLanes at a time. One per thread.
class DecoderLanes {
  public:
    explicit DecoderLanes(const Decoder& decoder);

    /// Samples queued (the lane the next one goes to).
    int size() const { return count_; }
    bool full() const { return count_ == kDecoderLanes; }
    /// Queues F (input_dim values); the queue must not be full.
    void add(const float* feature);
    /// f of the queued samples in the order they were added (size() values, valid until the next
    /// call); empties the queue.
    const float* evaluate();

  private:
    const Decoder& decoder_;
    DecoderWorkspace ws_;
    std::vector<float> features_;  ///< feature l of lane s at l * kDecoderLanes + s
    float out_[kDecoderLanes] = {};
    int count_ = 0;
};

/// DecoderLanes that carry a payload with each sample (a voxel's coordinate, a point's index) and
/// hand it back with the sample's f: the loops that evaluate many points need no array of their
/// own beside the lanes.
template <class Payload>
class DecoderLaneQueue {
  public:
    explicit DecoderLaneQueue(const Decoder& decoder) : lanes_(decoder) {}

    /// Queues F with its payload; when that fills the lanes, evaluates them and calls
    /// emit(payload, f) for each queued sample in the order they were added.
    template <class Emit>
    void add(const float* feature, const Payload& payload, Emit&& emit) {
        payload_[lanes_.size()] = payload;
        lanes_.add(feature);
        if (lanes_.full()) flush(emit);
    }

    /// Evaluates the samples still queued and calls emit(payload, f) for each.
    template <class Emit>
    void flush(Emit&& emit) {
        const int n = lanes_.size();
        const float* f = lanes_.evaluate();
        for (int s = 0; s < n; ++s) emit(payload_[s], f[s]);
    }

  private:
    DecoderLanes lanes_;
    Payload payload_[kDecoderLanes] = {};
};

}  // namespace shine
