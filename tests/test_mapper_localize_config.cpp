// The localiser's configuration checks (mapper/map_localizer.hpp validate): each bad setting is a
// ConfigError that names it under "localize.", and the defaults pass.
#include <gtest/gtest.h>

#include <functional>
#include <string>
#include <vector>

#include "shine/core/error.hpp"
#include "shine/mapper/map_localizer.hpp"

namespace {

struct BadSetting {
    const char* key;
    std::function<void(shine::LocalizeConfig&)> spoil;
};

}  // namespace

TEST(LocalizeConfig, EachBadSettingIsNamedUnderLocalize) {
    EXPECT_NO_THROW(shine::validate(shine::LocalizeConfig{}));
    const std::vector<BadSetting> bad = {
        {"voxel_size_m", [](shine::LocalizeConfig& c) { c.voxel_size_m = -1.0; }},
        {"max_range_m", [](shine::LocalizeConfig& c) { c.max_range_m = c.min_range_m; }},
        {"kernel_scales_m", [](shine::LocalizeConfig& c) { c.kernel_scales_m.clear(); }},
        {"kernel_scales_m",
         [](shine::LocalizeConfig& c) {
             c.kernel_scales_m = {0.1, 0.0};
         }},
        {"max_iterations", [](shine::LocalizeConfig& c) { c.max_iterations = 0; }},
        {"max_points", [](shine::LocalizeConfig& c) { c.max_points = -1; }},
        {"inlier_distance_m", [](shine::LocalizeConfig& c) { c.inlier_distance_m = 0.0; }},
        {"min_inlier_ratio", [](shine::LocalizeConfig& c) { c.min_inlier_ratio = 1.5; }},
        {"start_motion_scales",
         [](shine::LocalizeConfig& c) {
             c.start_motion_scales = {1.0, -0.5};
         }},
        {"start_yaw_range_deg", [](shine::LocalizeConfig& c) { c.start_yaw_range_deg = 120.0; }},
        {"start_yaw_step_deg", [](shine::LocalizeConfig& c) { c.start_yaw_step_deg = 0.0; }},
        {"prediction_good_score", [](shine::LocalizeConfig& c) { c.prediction_good_score = 1.5; }},
        {"track_min_start_score", [](shine::LocalizeConfig& c) { c.track_min_start_score = -0.1; }},
        {"icp_lookup_voxel_m", [](shine::LocalizeConfig& c) { c.icp_lookup_voxel_m = -0.25; }},
        {"icp_coarse_lookup_voxel_m",
         [](shine::LocalizeConfig& c) { c.icp_coarse_lookup_voxel_m = 0.001; }},
        {"icp_converged_translation_m",
         [](shine::LocalizeConfig& c) { c.icp_converged_translation_m = 0.0; }},
        {"icp_converged_translation_m",
         [](shine::LocalizeConfig& c) { c.icp_converged_rotation_rad = -1e-3; }},
        {"deep_search_registrations",
         [](shine::LocalizeConfig& c) { c.deep_search_registrations = -1; }},
    };
    for (const BadSetting& setting : bad) {
        shine::LocalizeConfig config;
        setting.spoil(config);
        try {
            shine::validate(config);
            ADD_FAILURE() << setting.key << ": accepted";
        } catch (const shine::ConfigError& e) {
            // The message starts with the section and the key (in a unity build another file's
            // check of the same name once answered with its own section).
            EXPECT_EQ(std::string(e.what()).rfind(std::string("localize.") + setting.key, 0), 0u)
                << e.what();
        }
    }
}
