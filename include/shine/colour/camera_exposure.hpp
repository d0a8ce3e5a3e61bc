// A camera's exposure along a drive: the gain of each mapped image against the exposure the
// map's colours were fitted at (vertex_colour_fit.hpp; the gains' geometric mean is 1), and the
// gain of any other image of the same camera read off them.
//
// Auto-exposure drifts with the scene (the real drive's gains go smoothly from 0.96 to 1.06), so
// an image the map never saw is best rendered at the exposure of the mapped images taken just
// before and after it: gain_at() interpolates the logarithm of the gain linearly in the frame
// number between the nearest mapped frames of that camera, and holds the first or last gain
// beyond them. A camera with no gain, or a track with none, renders at 1.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

namespace shine {

/// One mapped image's exposure gain: pixel = gain x the map's colour.
struct ExposureGain {
    std::string camera;     ///< the rig camera's name
    std::size_t frame = 0;  ///< the scan's frame number (ScanSequence::frame_number)
    double gain = 1.0;
};

class ExposureTrack {
  public:
    ExposureTrack() = default;
    /// Gains of any cameras and frames, in any order; a frame given twice keeps the last.
    /// Throws DataError for a gain that is not finite and positive.
    explicit ExposureTrack(std::vector<ExposureGain> gains);

    /// The gain `camera` had, or would have had, at `frame` (see the file comment).
    double gain_at(const std::string& camera, std::size_t frame) const;

    const std::vector<ExposureGain>& gains() const { return gains_; }
    bool empty() const { return gains_.empty(); }

  private:
    std::vector<ExposureGain> gains_;  ///< sorted by camera, then frame
};

}  // namespace shine
