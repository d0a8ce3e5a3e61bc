// Scale-free defaults (mapper_config.hpp, scene_preset.hpp): every length default of a mapping
// run follows the leaf size in proportion to its outdoor value at 0.2 m, unless the user set it;
// the scene preset (given, or inferred from the leaf) decides the range crop.
#include <gtest/gtest.h>

#include <string>
#include <utility>

#include "shine/core/error.hpp"
#include "shine/mapper/incremental_mapper.hpp"
#include "shine/mapper/map_sequence.hpp"
#include "shine/mapper/mapper_config.hpp"

namespace shine {
namespace {

/// Lengths computed as outdoor value * (leaf / 0.2) in double and stored in float: float keeps
/// ~7 digits, 1e-8 m on lengths below 0.3 m.
constexpr double kFloatToleranceM = 1e-7;

MapperConfig finalized(const std::string& yaml) {
    MapperConfig config;
    parse_config_yaml(yaml, "test.yaml", config);
    config.finalize();
    return config;
}

TEST(MapperConfigScale, OutdoorDefaultsAtTwentyCentimetresAreUntouched) {
    const MapperConfig defaults;
    MapperConfig config;
    config.finalize();
    EXPECT_EQ(config.resolved_scene(), ScenePreset::kOutdoor);
    // Bit for bit: the bundled street's mesh must not change.
    EXPECT_EQ(config.octree.leaf_size_m, 0.2);
    EXPECT_EQ(config.preprocess.min_range_m, 1.5);
    EXPECT_EQ(config.preprocess.max_range_m, 60.0);
    EXPECT_EQ(config.preprocess.voxel_downsample_m, 0.2);
    EXPECT_EQ(config.sampling.surface_band_m, 0.1f);
    EXPECT_EQ(config.normals.max_radius_m, 1.0f);
    EXPECT_EQ(config.trainer.sigma_m, 0.05f);
    EXPECT_EQ(config.incremental.surface_band_m, 0.15f);
    EXPECT_EQ(config_to_yaml(config), config_to_yaml(defaults));
}

TEST(MapperConfigScale, UnsetLengthsFollowTheLeafFromYaml) {
    const MapperConfig c = finalized("map:\n  leaf_size_m: 0.003\n");
    const double s = 0.003 / 0.2;
    EXPECT_EQ(c.resolved_scene(), ScenePreset::kObject);  // inferred from the leaf
    EXPECT_NEAR(c.preprocess.voxel_downsample_m, 0.2 * s, kFloatToleranceM);
    EXPECT_NEAR(c.sampling.surface_band_m, 0.0045, kFloatToleranceM);  // the object preset's
    EXPECT_NEAR(c.normals.max_radius_m, 1.0 * s, kFloatToleranceM);
    EXPECT_NEAR(c.trainer.sigma_m, 0.05 * s, kFloatToleranceM);
    EXPECT_NEAR(c.incremental.surface_band_m, 0.15 * s, kFloatToleranceM);
    // The dynamic filter's hit tolerance is twice the band (the data's accuracy).
    EXPECT_NEAR(c.dynamic.margin_m, 2 * 0.0045, kFloatToleranceM);
    // Ranges come from the object preset, not from the leaf.
    EXPECT_EQ(c.preprocess.min_range_m, 0.1);
    EXPECT_EQ(c.preprocess.max_range_m, 3.0);
    // Ratios and counts do not change.
    const MapperConfig defaults;
    EXPECT_EQ(c.sampling.free_space_start_ratio, defaults.sampling.free_space_start_ratio);
    EXPECT_EQ(c.normals.neighbors, defaults.normals.neighbors);
    EXPECT_EQ(c.bake.voxel_size_m, 0.0);  // 0 = half the leaf, already relative
}

TEST(MapperConfigScale, PoseEstimationLengthsFollowTheLeafAndRangesTheScene) {
    const MapperConfig c = finalized("map:\n  leaf_size_m: 0.003\n");
    const MapperConfig outdoor;
    const double s = 0.003 / 0.2;
    EXPECT_NEAR(c.odometry.voxel_size_m, outdoor.odometry.voxel_size_m * s, kFloatToleranceM);
    EXPECT_NEAR(c.odometry.icp_max_correspondence_m, outdoor.odometry.icp_max_correspondence_m * s,
                kFloatToleranceM);
    EXPECT_NEAR(c.odometry.sdf_kernel_scale_m, outdoor.odometry.sdf_kernel_scale_m * s,
                kFloatToleranceM);
    EXPECT_EQ(c.odometry.min_range_m, 0.1);  // the object preset's
    EXPECT_EQ(c.odometry.max_range_m, 3.0);
    EXPECT_EQ(c.odometry.max_iterations, outdoor.odometry.max_iterations);  // not a length
    const MapperConfig set = finalized(
        "map:\n  leaf_size_m: 0.003\nodometry:\n  voxel_size_m: 0.5\n  min_range_m: 1.5\n");
    EXPECT_EQ(set.odometry.voxel_size_m, 0.5);
    EXPECT_EQ(set.odometry.min_range_m, 1.5);
}

TEST(MapperConfigScale, OutdoorTenCentimetreLeavesKeepTheRanges) {
    const MapperConfig c = finalized("map:\n  leaf_size_m: 0.1\n");
    EXPECT_EQ(c.resolved_scene(), ScenePreset::kOutdoor);
    EXPECT_EQ(c.preprocess.min_range_m, 1.5);
    EXPECT_EQ(c.preprocess.max_range_m, 60.0);
    EXPECT_EQ(c.odometry.max_range_m, 30.0);  // the registration's own, half the mapped range
    EXPECT_NEAR(c.preprocess.voxel_downsample_m, 0.1, kFloatToleranceM);
    EXPECT_NEAR(c.sampling.surface_band_m, 0.1, kFloatToleranceM);  // the scene's, not the leaf's
    EXPECT_NEAR(c.trainer.sigma_m, 0.025, kFloatToleranceM);
    EXPECT_EQ(c.octree.num_levels, 4);  // the coarsest cell stays 0.8 m
}

TEST(MapperConfigScale, FinerOutdoorLeavesKeepTheCoarseLevels) {
    EXPECT_EQ(finalized("map:\n  leaf_size_m: 0.05\n  scene: outdoor\n").octree.num_levels, 5);
    // Less than a halving finer, or coarser: the default 3.
    EXPECT_EQ(finalized("map:\n  leaf_size_m: 0.15\n").octree.num_levels, 3);
    EXPECT_EQ(finalized("map:\n  leaf_size_m: 0.4\n").octree.num_levels, 3);
    // Not measured indoors or on objects: unchanged there.
    EXPECT_EQ(finalized("map:\n  scene: indoor\n").octree.num_levels, 3);
    EXPECT_EQ(finalized("map:\n  scene: indoor\n  leaf_size_m: 0.02\n").octree.num_levels, 3);
    EXPECT_EQ(finalized("map:\n  scene: object\n").octree.num_levels, 3);
    // A set count wins, also when it is the default's.
    EXPECT_EQ(finalized("map:\n  leaf_size_m: 0.1\n  num_levels: 3\n").octree.num_levels, 3);
}

TEST(MapperConfigScale, SetKeysDoNotFollow) {
    // Set to another value, and set to the outdoor default's own value: both are kept.
    const MapperConfig c = finalized(
        "map:\n  leaf_size_m: 0.003\n"
        "sampling:\n  surface_band_m: 0.01\n  normal_radius_m: 1.0\n"
        "training:\n  sigma_m: 0.05\n"
        "preprocess:\n  min_range_m: 0.5\n  voxel_downsample_m: 0\n");
    EXPECT_EQ(c.sampling.surface_band_m, 0.01f);
    EXPECT_EQ(c.normals.max_radius_m, 1.0f);
    EXPECT_EQ(c.trainer.sigma_m, 0.05f);
    EXPECT_EQ(c.preprocess.min_range_m, 0.5);
    EXPECT_EQ(c.preprocess.voxel_downsample_m, 0.0);
    // The unset ones still follow.
    EXPECT_EQ(c.preprocess.max_range_m, 3.0);
    EXPECT_NEAR(c.incremental.surface_band_m, 0.15 * 0.015, kFloatToleranceM);
}

TEST(MapperConfigScale, SceneAloneChoosesLeafAndRanges) {
    const MapperConfig object = finalized("map:\n  scene: object\n");
    EXPECT_EQ(object.octree.leaf_size_m, 0.003);
    EXPECT_EQ(object.preprocess.max_range_m, 3.0);
    EXPECT_NEAR(object.sampling.surface_band_m, 0.0045, kFloatToleranceM);
    const MapperConfig indoor = finalized("map:\n  scene: indoor\n");
    EXPECT_EQ(indoor.octree.leaf_size_m, 0.05);
    EXPECT_EQ(indoor.preprocess.min_range_m, 0.3);
    EXPECT_EQ(indoor.preprocess.max_range_m, 20.0);
    EXPECT_EQ(indoor.odometry.max_range_m, 20.0);  // the scene's whole range, as before
    // A set leaf wins over the preset's; the preset still decides the ranges.
    const MapperConfig outdoor_fine = finalized("map:\n  scene: outdoor\n  leaf_size_m: 0.05\n");
    EXPECT_EQ(outdoor_fine.octree.leaf_size_m, 0.05);
    EXPECT_EQ(outdoor_fine.preprocess.min_range_m, 1.5);
    EXPECT_NEAR(outdoor_fine.sampling.surface_band_m, 0.1, kFloatToleranceM);
    EXPECT_NEAR(indoor.sampling.surface_band_m, 0.03, kFloatToleranceM);
}

TEST(MapperConfigScale, FinalizeTwiceAndTheStoredYamlGiveTheSameConfig) {
    MapperConfig c = finalized("map:\n  leaf_size_m: 0.003\n");
    const std::string once = config_to_yaml(c);
    c.finalize();
    EXPECT_EQ(config_to_yaml(c), once);
    // map.vdb and checkpoints store config_to_yaml(): reading it back reproduces the run.
    MapperConfig back;
    parse_config_yaml(once, "stored", back);
    back.finalize();
    EXPECT_EQ(config_to_yaml(back), once);
}

TEST(MapperConfigScale, CommandLineMarksAreSetKeys) {
    // What `shine map --leaf-size-m 0.003` does: the flag is a set key like a YAML one.
    MapperConfig c;
    c.octree.leaf_size_m = 0.003;
    c.mark_set("map.leaf_size_m");
    c.sampling.surface_band_m = 0.3f;  // e.g. a flag that sets the default value on purpose
    c.mark_set("sampling.surface_band_m");
    c.finalize();
    EXPECT_EQ(c.sampling.surface_band_m, 0.3f);
    EXPECT_NEAR(c.trainer.sigma_m, 0.05 * 0.015, kFloatToleranceM);
    EXPECT_TRUE(c.is_set("map.leaf_size_m"));
    EXPECT_FALSE(c.is_set("training.sigma_m"));
}

TEST(MapperConfigScale, BadSceneNamesTheKey) {
    MapperConfig c;
    try {
        parse_config_yaml("map:\n  scene: forest\n", "test.yaml", c);
        FAIL() << "accepted scene 'forest'";
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("map.scene"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("object"), std::string::npos) << e.what();
    }
    MapperConfig direct;
    direct.scene = "street";
    EXPECT_THROW(direct.finalize(), ConfigError);
}

TEST(MapperConfigScale, AutomaticScheduleAtThreeMillimetresIsCapped) {
    // 250 * (0.2 / 0.003)^2 = 1.1 M steps, capped at 6250 steps of 32768 samples.
    const MapperConfig c = finalized("map:\n  leaf_size_m: 0.003\n");
    const BatchSchedule schedule = c.batch_schedule();
    EXPECT_EQ(schedule.iterations, 6250);
    EXPECT_EQ(schedule.batch_size, 32768);
    EXPECT_EQ(finalized("map:\n  leaf_size_m: 0.1\n").batch_schedule().iterations, 1000);
}

TEST(MapperConfigScale, AutomaticScheduleFollowsTheScenesCorners) {
    const MapperConfig object = finalized("map:\n  leaf_size_m: 0.003\n");
    // The object scene's 186,624 corners: the 250-step floor instead of the leaf's 6250.
    EXPECT_EQ(object.batch_schedule(186624).iterations, 250);
    // Twice the street's corners: 500 steps; far more than the leaf formula's cap: 6250.
    EXPECT_EQ(object.batch_schedule(2 * 438267).iterations, 500);
    EXPECT_EQ(object.batch_schedule(100000000).iterations, 6250);
    // Outdoors at 0.2 m: a street's corners, 250 steps; larger scenes in proportion (a 0.4 km
    // route's 1.72 M corners, 980), smaller ones never below 250.
    const MapperConfig street = finalized("");
    EXPECT_EQ(street.batch_schedule(438267).iterations, 250);
    EXPECT_EQ(street.batch_schedule(1717560).iterations, 980);
    EXPECT_EQ(street.batch_schedule(10 * 438267).iterations, 2500);
    EXPECT_EQ(street.batch_schedule(100000).iterations, 250);
    // At 0.1 m the same rule: the street's 1.66 M corners 947 steps, the real walk's 1.79 M
    // 1022.
    const MapperConfig fine = finalized("map:\n  leaf_size_m: 0.1\n");
    EXPECT_EQ(fine.batch_schedule(1660000).iterations, 947);
    EXPECT_EQ(fine.batch_schedule(1791171).iterations, 1022);
    // Set steps are never moved.
    EXPECT_EQ(finalized("training:\n  iterations: 1000\n").batch_schedule(1000).iterations, 1000);
}

TEST(BatchDefaults, OutdoorKeepsEveryPointDropsTheEikonalTermAndFineLeavesBakeInsideLevelOne) {
    const auto batch_config = [](double leaf_size_m, const char* set_key, const char* scene) {
        MapperConfig config;
        config.octree.leaf_size_m = leaf_size_m;
        config.scene = scene;
        if (set_key) config.mark_set(set_key);
        config.finalize();
        apply_batch_defaults(config);
        return config;
    };
    const MapperConfig fine = batch_config(0.1, nullptr, "outdoor");
    EXPECT_EQ(fine.bake.mask_level, 1);
    EXPECT_EQ(fine.preprocess.voxel_points, VoxelPoints::kAll);
    EXPECT_EQ(fine.sampling.every_point_share, SamplingConfig{}.every_point_share);
    // The street's leaves: every point too, 15 % of the draws over them, the bake as it was.
    const MapperConfig street = batch_config(0.2, nullptr, "outdoor");
    EXPECT_EQ(street.bake.mask_level, 0);
    EXPECT_EQ(street.preprocess.voxel_points, VoxelPoints::kAll);
    EXPECT_EQ(street.sampling.every_point_share, kCoarseOutdoorEveryPointShare);
    EXPECT_EQ(batch_config(0.4, nullptr, "outdoor").sampling.every_point_share,
              kCoarseOutdoorEveryPointShare);
    EXPECT_EQ(batch_config(0.2, "sampling.every_point_share", "outdoor").sampling.every_point_share,
              SamplingConfig{}.every_point_share);
    EXPECT_EQ(batch_config(0.2, "preprocess.voxel_points", "outdoor").preprocess.voxel_points,
              VoxelPoints::kNearest);
    EXPECT_EQ(batch_config(0.1, "bake.mask_level", "outdoor").bake.mask_level, 0);
    EXPECT_EQ(batch_config(0.1, "bake.mask_level", "outdoor").preprocess.voxel_points,
              VoxelPoints::kAll);
    EXPECT_EQ(batch_config(0.1, "preprocess.voxel_points", "outdoor").preprocess.voxel_points,
              VoxelPoints::kNearest);
    EXPECT_EQ(batch_config(0.1, "preprocess.voxel_points", "outdoor").bake.mask_level, 1);
    // No Eikonal term outdoors at any leaf with the automatic schedule, unless the weight is
    // set; a set step count keeps it.
    EXPECT_EQ(fine.trainer.eikonal_weight, 0.0f);
    EXPECT_EQ(street.trainer.eikonal_weight, 0.0f);
    EXPECT_EQ(batch_config(0.2, "training.eikonal_weight", "outdoor").trainer.eikonal_weight,
              TrainerConfig{}.eikonal_weight);
    MapperConfig set_steps;
    set_steps.iterations = 20;
    set_steps.mark_set("training.iterations");
    set_steps.finalize();
    apply_batch_defaults(set_steps);
    EXPECT_EQ(set_steps.trainer.eikonal_weight, TrainerConfig{}.eikonal_weight);
    const MapperConfig indoor = batch_config(0.05, nullptr, "indoor");
    EXPECT_EQ(indoor.trainer.eikonal_weight, TrainerConfig{}.eikonal_weight);
    EXPECT_GT(indoor.trainer.eikonal_weight, 0.0f);
    EXPECT_EQ(indoor.bake.mask_level, 0);
    EXPECT_EQ(indoor.preprocess.voxel_points, VoxelPoints::kNearest);
    EXPECT_EQ(indoor.sampling.every_point_share, SamplingConfig{}.every_point_share);
}

TEST(IncrementalDefaults, FineOutdoorLeavesTakeFifteenStepsPerScanUnlessSet) {
    const auto steps = [](double leaf_size_m, const char* scene, int set_steps) {
        MapperConfig config;
        config.octree.leaf_size_m = leaf_size_m;
        config.scene = scene;
        if (set_steps > 0) {
            config.incremental.iterations_per_frame = set_steps;
            config.mark_set("incremental.iterations_per_frame");
        }
        config.finalize();
        apply_incremental_defaults(config);
        return config.incremental.iterations_per_frame;
    };
    EXPECT_EQ(steps(0.1, "outdoor", 0), 15);
    EXPECT_EQ(steps(0.2, "outdoor", 0), 11);
    EXPECT_EQ(steps(0.05, "indoor", 0), 11);
    EXPECT_EQ(steps(0.1, "outdoor", 11), 11);  // a set count, even the default's, is kept
    EXPECT_EQ(steps(0.1, "outdoor", 20), 20);
}

TEST(IncrementalDefaults, FineOutdoorLeavesTakeTheStreetMapsNormalNeighbourhoodUnlessSet) {
    const auto normals = [](double leaf_size_m, const char* scene, const char* set_key) {
        MapperConfig config;
        config.octree.leaf_size_m = leaf_size_m;
        config.scene = scene;
        if (set_key) {
            config.mark_set(set_key);
            config.normals.max_radius_m = 0.3f;  // only kept where its key is set
            config.incremental.normal_neighbors = 12;
        }
        config.finalize();
        apply_incremental_defaults(config);
        return std::make_pair(config.normals.max_radius_m, config.incremental.normal_neighbors);
    };
    EXPECT_EQ(normals(0.1, "outdoor", nullptr), std::make_pair(1.0f, 24));
    EXPECT_EQ(normals(0.2, "outdoor", nullptr), std::make_pair(1.0f, 16));
    EXPECT_EQ(normals(0.05, "indoor", nullptr).second, 16);
    EXPECT_LT(normals(0.05, "indoor", nullptr).first, 1.0f);  // follows the leaf as before
    // A set key's value is kept.
    EXPECT_FLOAT_EQ(normals(0.1, "outdoor", "sampling.normal_radius_m").first, 0.3f);
    EXPECT_EQ(normals(0.1, "outdoor", "incremental.normal_neighbors").second, 12);
}

}  // namespace
TEST(DynamicObjectDefaults, OffOnTheObjectSceneUnlessSetAndOnElsewhere) {
    // Dropping compact objects whole is for cars and people: on the object scene the whole scan
    // is one compact object (dynamic_objects.hpp).
    EXPECT_EQ(finalized("map: {scene: object}\n").dynamic.objects.min_dynamic_share, 0.0f);
    EXPECT_EQ(finalized("map: {scene: object}\ndynamic: {object_min_dynamic_share: 0.3}\n")
                  .dynamic.objects.min_dynamic_share,
              0.3f);
    const float outdoor = DynamicObjectConfig{}.min_dynamic_share;
    EXPECT_GT(outdoor, 0.0f);
    EXPECT_EQ(finalized("map: {scene: outdoor}\n").dynamic.objects.min_dynamic_share, outdoor);
    EXPECT_EQ(finalized("map: {scene: indoor}\n").dynamic.objects.min_dynamic_share, outdoor);
    EXPECT_EQ(finalized("map: {leaf_size_m: 0.1}\n").dynamic.objects.min_dynamic_share, outdoor);
}

TEST(PoseRefinementDefaults, OffOnTheObjectSceneUnlessSetAndOnElsewhere) {
    // Measured to lose on the object scene (exact poses moved by up to 2.5 mm, 21.9 points of
    // F-score at 1 mm: docs/object_scale.md) and to win outdoors and indoors.
    const int rounds = PoseRefinementConfig{}.rounds;
    EXPECT_GT(rounds, 0);
    EXPECT_EQ(finalized("map: {scene: object}\n").refine.rounds, 0);
    EXPECT_EQ(finalized("map: {leaf_size_m: 0.003}\n").refine.rounds, 0);
    EXPECT_EQ(finalized("map: {scene: object}\nrefine: {rounds: 2}\n").refine.rounds, 2);
    EXPECT_EQ(finalized("map: {scene: outdoor}\n").refine.rounds, rounds);
    EXPECT_EQ(finalized("map: {scene: indoor}\n").refine.rounds, rounds);
    EXPECT_EQ(finalized("map: {leaf_size_m: 0.1}\n").refine.rounds, rounds);
}

}  // namespace shine
