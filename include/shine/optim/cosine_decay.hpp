// The learning-rate schedule of batch mode's run, of each incremental scan's steps and of the
// consolidation: cosine decay from the initial rate to final_ratio of it.
#pragma once

#include <cmath>

namespace shine {

/// The factor on the initial learning rate at step `step` of `steps` (0-based): 1 at the first
/// step, `final_ratio` at the last, 0.5 * (1 + cos(pi * step / (steps - 1))) between them; a
/// single step takes final_ratio.
inline double cosine_decay_ratio(int step, int steps, double final_ratio) {
    const double progress = steps > 1 ? static_cast<double>(step) / (steps - 1) : 1.0;
    return final_ratio + (1.0 - final_ratio) * 0.5 * (1.0 + std::cos(M_PI * progress));
}

}  // namespace shine
