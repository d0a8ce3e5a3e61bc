// cosine_decay_ratio: the learning-rate schedule shared by batch mode, each incremental scan and
// the consolidation.
#include <gtest/gtest.h>

#include <cmath>

#include "shine/optim/cosine_decay.hpp"

namespace shine {
namespace {

TEST(CosineDecay, StartsAtOneEndsAtTheFinalRatioAndPassesTheMeanHalfway) {
    EXPECT_DOUBLE_EQ(cosine_decay_ratio(0, 11, 0.1), 1.0);
    EXPECT_DOUBLE_EQ(cosine_decay_ratio(10, 11, 0.1), 0.1);
    EXPECT_NEAR(cosine_decay_ratio(5, 11, 0.1), 0.55, 1e-12);  // cos(pi / 2) = 0
    // A quarter of the way: 0.1 + 0.9 * 0.5 * (1 + cos(pi / 4)).
    EXPECT_NEAR(cosine_decay_ratio(1, 5, 0.1), 0.1 + 0.45 * (1.0 + std::sqrt(0.5)), 1e-12);
    for (int step = 1; step < 11; ++step) {
        EXPECT_LT(cosine_decay_ratio(step, 11, 0.1), cosine_decay_ratio(step - 1, 11, 0.1));
    }
    EXPECT_DOUBLE_EQ(cosine_decay_ratio(0, 1, 0.25), 0.25);  // a single step: the final rate
}

}  // namespace
}  // namespace shine
