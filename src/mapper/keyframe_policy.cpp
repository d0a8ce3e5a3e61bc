#include "shine/mapper/keyframe_policy.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/core/median.hpp"
#include "shine/io/binary_stream.hpp"
#include "shine/mapper/scan_odometry.hpp"

namespace shine {
namespace {
constexpr std::size_t kTrainHistory = 8;  ///< keyframes whose training time the account expects

void require_keyframes(bool ok, const char* key, const std::string& rule) {
    if (!ok) throw ConfigError(std::string("keyframes.") + key + " must be " + rule);
}
}  // namespace

const char* to_string(KeyframeReason reason) {
    switch (reason) {
        case KeyframeReason::kDisabled:
            return "disabled";
        case KeyframeReason::kFirst:
            return "first";
        case KeyframeReason::kWarmup:
            return "warm-up";
        case KeyframeReason::kCoverage:
            return "coverage";
        case KeyframeReason::kMotion:
            return "motion";
        case KeyframeReason::kInterval:
            return "interval";
        case KeyframeReason::kRedundant:
            return "redundant";
        case KeyframeReason::kBudget:
            return "budget";
        case KeyframeReason::kBusy:
            return "busy";
    }
    return "?";
}

KeyframePolicy::KeyframePolicy(const KeyframeConfig& config) : config_(config) {
    require_keyframes(config.min_translation_m > 0.0, "min_translation_m", "> 0");
    require_keyframes(config.min_rotation_deg > 0.0, "min_rotation_deg", "> 0");
    require_keyframes(config.max_interval_scans >= 1, "max_interval_scans", ">= 1");
    require_keyframes(config.min_coverage >= 0.0 && config.min_coverage <= 1.0, "min_coverage",
                      "in [0, 1]");
    require_keyframes(
        config.forced_coverage >= 0.0 && config.forced_coverage <= config.min_coverage,
        "forced_coverage", "in [0, keyframes.min_coverage]");
    require_keyframes(config.max_ms_per_scan >= 0.0, "max_ms_per_scan", ">= 0 (0: no budget)");
    require_keyframes(config.max_saved_scans >= 1.0, "max_saved_scans", ">= 1");
    require_keyframes(config.max_deferred_scans >= 0, "max_deferred_scans", ">= 0");
}

double KeyframePolicy::expected_train_seconds() const {
    if (train_seconds_.empty()) return 0.0;
    return median(std::vector<double>(train_seconds_.begin(), train_seconds_.end()));
}

KeyframeChoice KeyframePolicy::choose(const OdometryRecord& record,
                                      const Eigen::Isometry3d& T_world_sensor) const {
    if (!config_.enabled) return {true, KeyframeReason::kDisabled};
    if (!has_keyframe_) return {true, KeyframeReason::kFirst};
    // A pose that is not the map's registration: ICP's warm-up, or the prediction.
    if (record.source != PoseSource::kSdf) return {true, KeyframeReason::kWarmup};
    const double coverage = record.points > 0 ? static_cast<double>(record.valid_points) /
                                                    static_cast<double>(record.points)
                                              : 0.0;
    const Eigen::Isometry3d moved = last_keyframe_.inverse() * T_world_sensor;
    const double turned_deg = Eigen::AngleAxisd(moved.linear()).angle() * 180.0 / M_PI;
    KeyframeChoice choice{false, KeyframeReason::kRedundant};
    if (coverage < config_.min_coverage) {
        choice = {true, KeyframeReason::kCoverage};
    } else if (moved.translation().norm() >= config_.min_translation_m ||
               turned_deg >= config_.min_rotation_deg) {
        choice = {true, KeyframeReason::kMotion};
    } else if (since_keyframe_ + 1 >= config_.max_interval_scans) {
        choice = {true, KeyframeReason::kInterval};
    }
    if (choice.train && config_.max_ms_per_scan > 0.0 && coverage >= config_.forced_coverage &&
        saved_s_ < expected_train_seconds()) {
        choice = {false, KeyframeReason::kBudget};
    }
    return choice;
}

void KeyframePolicy::record(const KeyframeChoice& choice, const Eigen::Isometry3d& T_world_sensor,
                            double wall_seconds, double train_seconds) {
    if (choice.train) {
        ++counts_.trained;
        has_keyframe_ = true;
        last_keyframe_ = T_world_sensor;
        since_keyframe_ = 0;
        train_seconds_.push_back(train_seconds);
        if (train_seconds_.size() > kTrainHistory) train_seconds_.pop_front();
    } else {
        ++counts_.deferred;
        if (choice.reason == KeyframeReason::kBudget) ++counts_.over_budget;
        if (choice.reason == KeyframeReason::kBusy) ++counts_.busy;
        ++since_keyframe_;
    }
    if (config_.max_ms_per_scan > 0.0) {
        const double budget_s = 1e-3 * config_.max_ms_per_scan;
        saved_s_ = std::min(saved_s_ + budget_s - wall_seconds, config_.max_saved_scans * budget_s);
    }
}

void KeyframePolicy::save(BinaryWriter& out) const {
    out.tag("keyframes");
    out.value<std::uint64_t>(counts_.trained);
    out.value<std::uint64_t>(counts_.deferred);
    out.value<std::uint64_t>(counts_.over_budget);
    out.value<std::uint64_t>(counts_.skipped);
    out.value<std::uint64_t>(counts_.busy);
    out.value<std::uint8_t>(has_keyframe_ ? 1 : 0);
    out.array(last_keyframe_.matrix().data(), 16);
    out.value<std::int32_t>(since_keyframe_);
    out.value(saved_s_);
    out.array(std::vector<double>(train_seconds_.begin(), train_seconds_.end()));
}

void KeyframePolicy::load(BinaryReader& in) {
    in.expect_tag("keyframes");
    counts_ = KeyframeCounts{};
    counts_.trained = in.value<std::uint64_t>("keyframes trained");
    counts_.deferred = in.value<std::uint64_t>("keyframes deferred");
    counts_.over_budget = in.value<std::uint64_t>("keyframes over budget");
    counts_.skipped = in.value<std::uint64_t>("keyframes skipped");
    counts_.busy = in.value<std::uint64_t>("keyframes deferred while busy");
    has_keyframe_ = in.value<std::uint8_t>("keyframe seen") != 0;
    in.array_into(last_keyframe_.matrix().data(), 16, "last keyframe pose");
    since_keyframe_ = in.value<std::int32_t>("scans since the keyframe");
    saved_s_ = in.value<double>("keyframe account");
    const std::vector<double> seconds = in.array<double>("keyframe training seconds");
    train_seconds_.assign(seconds.begin(), seconds.end());
}

}  // namespace shine
