// Configuration YAML whose values or keys are lists or mappings where a single value belongs:
// each must be a ConfigError naming the key, not a yaml-cpp exception (found by fuzz_config_yaml,
// fuzz/corpus/fuzz_config_yaml/regression_mapping_as_value.yaml).
#include <gtest/gtest.h>

#include <string>

#include "shine/core/error.hpp"
#include "shine/mapper/mapper_config.hpp"

namespace shine {
namespace {

void expect_config_error(const std::string& yaml, const std::string& fragment) {
    MapperConfig config;
    try {
        parse_config_yaml(yaml, "test.yaml", config);
        ADD_FAILURE() << "accepted:\n" << yaml;
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
}

TEST(ConfigYaml, NonScalarValuesAndKeysAreConfigErrors) {
    expect_config_error("preprocess:\n  invalid_points: {leaf_size_m: 0.1}\n",
                        "preprocess.invalid_points");
    expect_config_error("map:\n  feature_precision: [float16]\n", "map.feature_precision");
    expect_config_error("map:\n  {a: 1}: 2\n", "section 'map'");
    expect_config_error("[map]: {leaf_size_m: 0.1}\n", "section name");
}

TEST(ConfigYaml, MaxMapMbIsReadAndChecked) {
    MapperConfig config;
    parse_config_yaml("map:\n  max_map_mb: 12.5\n", "test.yaml", config);
    EXPECT_EQ(config.max_map_mb, 12.5);
    expect_config_error("map:\n  max_map_mb: -1\n", "map.max_map_mb");
    // It survives the round trip through the YAML stored in map.vdb.
    MapperConfig back;
    parse_config_yaml(config_to_yaml(config), "stored", back);
    EXPECT_EQ(back.max_map_mb, 12.5);
}

TEST(ConfigYaml, VoxelPointsAndEveryPointShareAreReadCheckedAndStored) {
    MapperConfig config;
    parse_config_yaml("preprocess:\n  voxel_points: all\nsampling:\n  every_point_share: 0.25\n",
                      "test.yaml", config);
    EXPECT_EQ(config.preprocess.voxel_points, VoxelPoints::kAll);
    EXPECT_EQ(config.sampling.every_point_share, 0.25f);
    EXPECT_TRUE(config.is_set("preprocess.voxel_points"));
    MapperConfig back;
    parse_config_yaml(config_to_yaml(config), "stored", back);
    EXPECT_EQ(back.preprocess.voxel_points, VoxelPoints::kAll);
    EXPECT_EQ(back.sampling.every_point_share, 0.25f);
    expect_config_error("preprocess:\n  voxel_points: every\n",
                        "'preprocess.voxel_points': expected 'nearest' or 'all', got 'every'");
    expect_config_error("preprocess:\n  voxel_points: [all]\n", "preprocess.voxel_points");
    expect_config_error("sampling:\n  every_point_share: 1.5\n", "sampling.every_point_share");
    expect_config_error("sampling:\n  every_point_share: -0.1\n", "sampling.every_point_share");
    // The neighbouring key keeps its message.
    expect_config_error("preprocess:\n  invalid_points: skip\n",
                        "'preprocess.invalid_points': expected 'error' or 'drop', got 'skip'");
}

}  // namespace
}  // namespace shine

namespace shine {
namespace {

TEST(ConfigYaml, OriginAndWorldCropAreListsOfNumbersThatReadBack) {
    MapperConfig config;
    parse_config_yaml(
        "map:\n  origin_world_m: [500000, 5000000, 0]\n"
        "preprocess:\n  crop_world_m: [499990.5, 4999990, -5, 500040, 5000010.25, 30]\n",
        "test.yaml", config);
    config.finalize();
    EXPECT_EQ(config.origin_world_m, (std::vector<double>{500000, 5000000, 0}));
    EXPECT_EQ(config.crop_world_m,
              (std::vector<double>{499990.5, 4999990, -5, 500040, 5000010.25, 30}));
    MapperConfig again;
    parse_config_yaml(config_to_yaml(config), "written", again);
    EXPECT_EQ(again.origin_world_m, config.origin_world_m);
    EXPECT_EQ(again.crop_world_m, config.crop_world_m);
    // [] is the default: no fixed origin, no crop.
    MapperConfig unset;
    parse_config_yaml(config_to_yaml(MapperConfig{}), "defaults", unset);
    EXPECT_TRUE(unset.origin_world_m.empty());
    EXPECT_TRUE(unset.crop_world_m.empty());

    expect_config_error("map:\n  origin_world_m: [1, 2]\n", "needs 3 numbers");
    expect_config_error("map:\n  origin_world_m: 5\n", "must be a list");
    expect_config_error("preprocess:\n  crop_world_m: [0, 0, 0, 1, 1, .nan]\n", "finite");
    MapperConfig inverted;
    parse_config_yaml("preprocess:\n  crop_world_m: [0, 0, 0, 1, -1, 1]\n", "t", inverted);
    EXPECT_THROW(inverted.finalize(), ConfigError);
}

}  // namespace
}  // namespace shine
