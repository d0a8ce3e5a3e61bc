// The progress line's ETA: none while the estimate is unstable, the rate after the first step
// once it is; and the line keeps the format the Blender add-on parses.
#include <gtest/gtest.h>

#include <regex>
#include <string>

#include "shine/core/progress.hpp"

namespace shine {
namespace {

constexpr double kToleranceS = 1e-9;

// A 250-step stage whose first step took 0.6 s (setup) and whose other steps take 20 ms each:
// 5.58 s in all. Measured from the stage's start, step 1 promised 149 s more.
TEST(ProgressEta, NoneAfterTheFirstStep) {
    EXPECT_FALSE(progress_eta_seconds(1, 0.6, 1, 0.6, 250));
    EXPECT_FALSE(progress_eta_seconds(1, 0.6, 2, 0.62, 250));
}

TEST(ProgressEta, NoneUntilFivePercentAndOneSecond) {
    // 12 steps after the first (< 5 % of 250) in 1.2 s: too few steps.
    EXPECT_FALSE(progress_eta_seconds(1, 0.6, 13, 1.8, 250));
    // 30 steps after the first in 0.6 s: too little time.
    EXPECT_FALSE(progress_eta_seconds(1, 0.6, 31, 1.2, 250));
}

TEST(ProgressEta, RateSinceTheFirstStep) {
    // 50 steps after the first in 1.0 s: 20 ms a step, 199 steps left.
    const auto eta = progress_eta_seconds(1, 0.6, 51, 1.6, 250);
    ASSERT_TRUE(eta);
    EXPECT_NEAR(*eta, 199 * 0.02, kToleranceS);
}

TEST(ProgressEta, ResumedStageCountsOnlyItsOwnSteps) {
    // Resumed at step 200 of 250: 20 more steps in 2 s, 30 left.
    const auto eta = progress_eta_seconds(200, 0.0, 220, 2.0, 250);
    ASSERT_TRUE(eta);
    EXPECT_NEAR(*eta, 3.0, kToleranceS);
}

TEST(ProgressEta, NoneWhenDone) { EXPECT_FALSE(progress_eta_seconds(1, 0.1, 250, 5.0, 250)); }

// blender_addon/shinevdb/map_job.py's _PROGRESS_LINE, without Python's group names.
const std::regex kAddonLine(
    R"(^(\S+)\s+\[[#.]*\]\s+(\d+)/(\d+)\s+([\d.]+) s(?:, ETA (\d+) s)?(?:\s+(.*))?$)");

TEST(ProgressLine, FirstStepHasNoEtaAndParses) {
    testing::internal::CaptureStderr();
    {
        Progress progress("train", 250);
        progress.update(1, "bce 0.6931");
        progress.finish();
    }
    const std::string out = testing::internal::GetCapturedStderr();
    const auto newline = out.find('\n');
    ASSERT_NE(newline, std::string::npos) << out;
    const std::string first = out.substr(0, newline);
    const std::string last = out.substr(newline + 1, out.find('\n', newline + 1) - newline - 1);
    EXPECT_EQ(first.find("ETA"), std::string::npos) << first;
    std::smatch match;
    ASSERT_TRUE(std::regex_match(first, match, kAddonLine)) << first;
    EXPECT_EQ(match[1].str(), "train");
    EXPECT_EQ(match[2].str(), "1");
    EXPECT_EQ(match[3].str(), "250");
    EXPECT_FALSE(match[5].matched);
    EXPECT_EQ(match[6].str(), "bce 0.6931");
    ASSERT_TRUE(std::regex_match(last, match, kAddonLine)) << last;
    EXPECT_EQ(match[2].str(), "250");
}

}  // namespace
}  // namespace shine
