// The in-memory layout of the feature map: stable rows, lookups that agree with a brute-force
// index, and OpenVDB structure bytes of known allocations against measured bounds.
#include <gtest/gtest.h>
#include <openvdb/openvdb.h>

#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <tuple>

#include "shine/core/error.hpp"
#include "shine/map/feature_octree.hpp"
#include "shine/map/feature_octree_impl.hpp"
#include "shine/map/feature_table.hpp"

using namespace shine;

namespace {

using CornerKey = std::tuple<int, int, int, int>;  // level, x, y, z

// Points on the plane z = 0 over [x0, x0 + size_m) x [y0, y0 + size_m), `spacing_m` apart.
std::vector<Eigen::Vector3f> plane_points(float x0, float y0, float size_m, float spacing_m) {
    std::vector<Eigen::Vector3f> points;
    const int n = static_cast<int>(size_m / spacing_m);
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j)
            points.emplace_back(x0 + i * spacing_m, y0 + j * spacing_m, 0.0f);
    }
    return points;
}

// Every allocated corner with its row, found by brute force over the cells of each level.
std::map<CornerKey, std::int32_t> all_rows(const FeatureOctree& octree) {
    std::map<CornerKey, std::int32_t> rows;
    for (int level = 0; level < octree.num_levels(); ++level) {
        for (const Eigen::Vector3i& cell : octree.cells(level)) {
            for (int c = 0; c < 8; ++c) {
                const Eigen::Vector3i corner = cell + Eigen::Vector3i(c & 1, (c >> 1) & 1, c >> 2);
                rows[{level, corner.x(), corner.y(), corner.z()}] =
                    octree.corner_row(level, corner);
            }
        }
    }
    return rows;
}

// Bytes of the same corners in OpenVDB's default layout (one Int32Grid per level, 5-4-3 tree),
// which is how the map was kept before: the reference the packed layout is measured against.
std::size_t default_int32_grid_bytes(const FeatureOctree& octree) {
    std::size_t bytes = 0;
    for (int level = 0; level < octree.num_levels(); ++level) {
        auto grid = openvdb::Int32Grid::create(-1);
        auto accessor = grid->getAccessor();
        for (const auto& [key, row] : all_rows(octree)) {
            if (std::get<0>(key) != level) continue;
            accessor.setValue(openvdb::Coord(std::get<1>(key), std::get<2>(key), std::get<3>(key)),
                              row);
        }
        bytes += grid->memUsage();
    }
    return bytes;
}

// Every row of `rows` is distinct and in [0, num_corners).
void expect_distinct_rows(const std::map<CornerKey, std::int32_t>& rows, std::size_t num_corners) {
    std::vector<std::uint8_t> seen(num_corners, 0);
    for (const auto& [key, row] : rows) {
        ASSERT_GE(row, 0);
        ASSERT_LT(static_cast<std::size_t>(row), num_corners);
        ASSERT_FALSE(seen[row]) << "row " << row << " used twice";
        seen[row] = 1;
    }
}

// Checks CellLookup::find_cell and FeatureOctree::find_cell against corner_row() at `samples`
// random points of [-20, 20]^2 x [-1, 3]: same presence, same rows; with `expected`, corner_row()
// also gives each corner its row there (-1 for a corner not in it). Returns the cells found.
int check_lookups(const FeatureOctree& octree, std::mt19937& rng, int samples,
                  const std::map<CornerKey, std::int32_t>* expected = nullptr) {
    std::uniform_real_distribution<float> u(-20.0f, 20.0f), uz(-1.0f, 3.0f);
    CellLookup lookup(octree);
    int found = 0;
    for (int i = 0; i < samples; ++i) {
        const Eigen::Vector3f p(u(rng), u(rng), uz(rng));
        for (int level = 0; level < octree.num_levels(); ++level) {
            const double cell_m = octree.cell_size_m(level);
            const Eigen::Vector3i cell(static_cast<int>(std::floor(p.x() / cell_m)),
                                       static_cast<int>(std::floor(p.y() / cell_m)),
                                       static_cast<int>(std::floor(p.z() / cell_m)));
            LevelCorners a, b;
            const bool has = lookup.find_cell(level, p, a);
            EXPECT_EQ(has, octree.find_cell(level, p, b));
            bool complete = true;
            for (int c = 0; c < 8; ++c) {
                const Eigen::Vector3i corner = cell + Eigen::Vector3i(c & 1, (c >> 1) & 1, c >> 2);
                const std::int32_t row = octree.corner_row(level, corner);
                if (expected) {
                    const auto it = expected->find({level, corner.x(), corner.y(), corner.z()});
                    EXPECT_EQ(row, it == expected->end() ? -1 : it->second);
                }
                if (row < 0) {
                    complete = false;
                } else if (has) {
                    EXPECT_EQ(a.rows[c], row);
                    EXPECT_EQ(b.rows[c], row);
                }
            }
            EXPECT_EQ(has, complete);
            found += has;
        }
    }
    return found;
}

}  // namespace

TEST(FeatureOctreeLayout, RowsStayPutAsTheMapGrowsAndLookupsAgreeWithTheCorners) {
    FeatureOctreeConfig config;
    config.leaf_size_m = 0.25;
    config.num_levels = 3;
    FeatureOctree octree(config);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-20.0f, 20.0f), uz(-1.0f, 3.0f);
    std::map<CornerKey, std::int32_t> before;
    for (int call = 0; call < 4; ++call) {
        std::vector<Eigen::Vector3f> points;
        for (int i = 0; i < 3000; ++i) points.emplace_back(u(rng), u(rng), uz(rng));
        const std::size_t added = octree.allocate_cells(points);
        const auto rows = all_rows(octree);
        ASSERT_EQ(rows.size(), octree.num_corners());
        EXPECT_EQ(rows.size(), before.size() + added);
        // Old corners keep their rows; all rows are distinct and in range.
        for (const auto& [key, row] : before) ASSERT_EQ(rows.at(key), row);
        expect_distinct_rows(rows, octree.num_corners());
        before = rows;
    }
    // Each row holds its corner's initial feature (a pure function of seed, level and corner).
    std::vector<float> expected(config.feature_dim), stored(config.feature_dim);
    for (const auto& [key, row] : before) {
        const auto [level, x, y, z] = key;
        FeatureOctree::initial_feature(config.seed, level, Eigen::Vector3i(x, y, z),
                                       config.init_std, expected.data(), config.feature_dim);
        octree.features().get_row(row, stored.data());
        ASSERT_EQ(stored, expected) << "level " << level << " corner " << x << "," << y << "," << z;
    }
    // Lookups through a CellLookup and find_cell return the rows of the cell's corners.
    EXPECT_GT(check_lookups(octree, rng, 20000, &before), 1000);
}

TEST(FeatureOctreeLayout, RowsRenumberedInTreeOrderKeepEveryCornersFeatureAndLookups) {
    FeatureOctreeConfig config;
    config.leaf_size_m = 0.25;
    config.num_levels = 3;
    config.feature_precision = FeaturePrecision::kFloat16;
    FeatureOctree octree(config);
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(-20.0f, 20.0f), uz(-1.0f, 3.0f);
    const auto random_points = [&](int n) {
        std::vector<Eigen::Vector3f> points;
        for (int i = 0; i < n; ++i) points.emplace_back(u(rng), u(rng), uz(rng));
        return points;
    };
    // Several allocations: rows in allocation order, with dead slots from leaves that grew.
    for (int call = 0; call < 4; ++call) octree.allocate_cells(random_points(3000));
    const auto rows_before = all_rows(octree);
    std::map<CornerKey, std::vector<float>> feature_before;
    std::vector<float> value(config.feature_dim);
    for (const auto& [key, row] : rows_before) {
        octree.features().get_row(row, value.data());
        feature_before[key] = value;
    }

    octree.renumber_rows_in_tree_order();
    const auto rows_after = all_rows(octree);
    ASSERT_EQ(rows_after.size(), rows_before.size());
    ASSERT_EQ(octree.num_corners(), rows_before.size());
    // A permutation: every corner keeps its feature, level 0's rows come first, then level 1's.
    expect_distinct_rows(rows_after, octree.num_corners());
    std::vector<std::int32_t> level_min(3, std::numeric_limits<std::int32_t>::max()),
        level_max(3, -1);
    int moved = 0;
    for (const auto& [key, row] : rows_after) {
        octree.features().get_row(row, value.data());
        ASSERT_EQ(value, feature_before.at(key));
        const int level = std::get<0>(key);
        level_min[level] = std::min(level_min[level], row);
        level_max[level] = std::max(level_max[level], row);
        moved += row != rows_before.at(key);
    }
    EXPECT_GT(moved, 1000);  // the allocation order was not the tree order
    // Every level's rows follow from its slots, so lookups take the path without a table read.
    for (const LevelIndex& level : octree.impl().levels) EXPECT_GE(level.identity_base, 0);
    EXPECT_EQ(level_min[0], 0);
    EXPECT_EQ(level_min[1], level_max[0] + 1);
    EXPECT_EQ(level_min[2], level_max[1] + 1);
    EXPECT_GT(check_lookups(octree, rng, 20000), 1000);

    // The map grows again after the renumbering: old corners keep their new rows, new corners
    // get rows after them, and lookups still agree (the rows no longer follow the tree order).
    const std::size_t added = octree.allocate_cells(random_points(2000));
    ASSERT_GT(added, 0u);
    const auto rows_grown = all_rows(octree);
    for (const auto& [key, row] : rows_after) ASSERT_EQ(rows_grown.at(key), row);
    EXPECT_EQ(octree.impl().levels[0].identity_base, -1);
    EXPECT_GT(check_lookups(octree, rng, 20000), 1000);
    // And renumbered once more, the lookups agree again.
    octree.renumber_rows_in_tree_order();
    EXPECT_GT(check_lookups(octree, rng, 20000), 1000);
}

TEST(FeatureOctreeLayout, StructureOfAKnownAllocationStaysBelowMeasuredBounds) {
    // A 40 m x 40 m ground plane at z = 0 sampled every 5 cm, 0.2 m leaves, 3 levels: 4 B and
    // 1 bit per corner plus the trees. Measured: 163,881 corners, 863,664 structure bytes; the
    // default Int32Grid layout of the same corners: 11,317,128 bytes.
    constexpr std::size_t kMeasuredCorners = 163881;
    constexpr std::size_t kStructureBoundBytes = 900000;  // measured 863,664
    FeatureOctreeConfig config;
    config.leaf_size_m = 0.2;
    FeatureOctree octree(config);
    octree.allocate_cells(plane_points(-20.0f, -20.0f, 40.0f, 0.05f));
    EXPECT_EQ(octree.num_corners(), kMeasuredCorners);
    EXPECT_LT(octree.structure_bytes(), kStructureBoundBytes);
    // Counting each corner's 4-byte row, the structure is under 5.5 B per corner (measured 5.27)
    EXPECT_LT(octree.structure_bytes(), 5.5 * octree.num_corners());
    // ... and under a tenth of OpenVDB's default Int32 index grids for the same corners.
    EXPECT_LT(10 * octree.structure_bytes(), default_int32_grid_bytes(octree));
    EXPECT_EQ(octree.memory_bytes(), octree.structure_bytes() + octree.feature_bytes());
    EXPECT_EQ(octree.feature_bytes(), octree.num_corners() * config.feature_dim * sizeof(float));
}

TEST(FeatureOctreeLayout, AMapStraddlingTheOriginCostsNoMoreThanOneAwayFromIt) {
    // The index shift centres the first allocation in a root child, so where the map lies does
    // not change its structure: the same plane around the origin and 2 km away (a whole number
    // of leaf nodes, so that the leaves align the same way).
    FeatureOctreeConfig config;
    config.leaf_size_m = 1.0;
    FeatureOctree at_origin(config), far_away(config);
    at_origin.allocate_cells(plane_points(-30.0f, -30.0f, 60.0f, 0.25f));
    far_away.allocate_cells(plane_points(2018.0f, 2018.0f, 60.0f, 0.25f));
    ASSERT_EQ(at_origin.num_corners(), far_away.num_corners());
    EXPECT_EQ(at_origin.structure_bytes(), far_away.structure_bytes());
    // Measured 141,024 bytes for 16,041 corners; OpenVDB's default Int32 grids of the same
    // corners, with 8 root children per level around the origin: 7,723,784 bytes.
    EXPECT_LT(at_origin.structure_bytes(), 150000u);
    EXPECT_LT(50 * at_origin.structure_bytes(), default_int32_grid_bytes(at_origin));
}

TEST(FeatureTable, Float16RoundsToNearestAndHalvesTheBytes) {
    FeatureTable table(4, FeaturePrecision::kFloat32);
    table.resize(3);
    const float values[4] = {0.1f, -1.0f / 3.0f, 1e-5f, 2.0f};
    table.set_row(1, values);
    EXPECT_EQ(table.bytes(), 3 * 4 * sizeof(float));
    table.set_precision(FeaturePrecision::kFloat16);
    EXPECT_EQ(table.bytes(), 3 * 4 * 2u);
    EXPECT_EQ(table.precision(), FeaturePrecision::kFloat16);
    float back[4];
    table.get_row(1, back);
    for (int i = 0; i < 4; ++i) {
        // Half has an 11-bit significand: relative error <= 2^-11 for normal numbers; 1e-5 is
        // subnormal in half (spacing 2^-24 ~ 6e-8).
        EXPECT_NEAR(back[i], values[i], std::max(std::abs(values[i]) * 0.00049f, 6e-8f)) << i;
        EXPECT_EQ(back[i], static_cast<float>(Imath::half(values[i])));
    }
    EXPECT_THROW(table.floats(), Error);
    EXPECT_NO_THROW(table.halves());
    table.set_precision(FeaturePrecision::kFloat32);  // exact: every half is a float
    float again[4];
    table.get_row(1, again);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(again[i], back[i]);
    EXPECT_THROW(table.halves(), Error);
    EXPECT_EQ(parse_feature_precision("float16", "k"), FeaturePrecision::kFloat16);
    EXPECT_THROW(parse_feature_precision("fp16", "map.feature_precision"), ConfigError);
}

TEST(FeatureOctreeClone, IsADeepCopyThatKeepsItsRowsWhileTheOriginalGrows) {
    FeatureOctreeConfig config;
    config.leaf_size_m = 0.2;
    FeatureOctree octree(config);
    octree.allocate_cells(plane_points(0.0f, 0.0f, 2.0f, 0.1f));
    const FeatureOctree copy = octree.clone();
    const auto rows = all_rows(octree);
    ASSERT_EQ(all_rows(copy), rows);
    ASSERT_EQ(copy.num_corners(), octree.num_corners());
    std::vector<float> before(static_cast<std::size_t>(config.feature_dim));
    copy.features().get_row(0, before.data());

    // The original grows and its first row changes: the copy keeps both as they were.
    octree.allocate_cells(plane_points(5.0f, 5.0f, 2.0f, 0.1f));
    const std::vector<float> changed(static_cast<std::size_t>(config.feature_dim), 7.0f);
    octree.features().set_row(0, changed.data());
    EXPECT_GT(octree.num_corners(), copy.num_corners());
    EXPECT_EQ(all_rows(copy), rows);
    std::vector<float> after(before.size());
    copy.features().get_row(0, after.data());
    EXPECT_EQ(after, before);
    LevelCorners corners;
    EXPECT_FALSE(copy.find_cell(0, Eigen::Vector3f(6.0f, 6.0f, 0.0f), corners));
    EXPECT_TRUE(octree.find_cell(0, Eigen::Vector3f(6.0f, 6.0f, 0.0f), corners));
    EXPECT_TRUE(copy.find_cell(0, Eigen::Vector3f(1.0f, 1.0f, 0.0f), corners));
}

TEST(FeatureOctreeCopy, SharedCornersTakeTheSourcesFeaturesTheOthersKeepTheirs) {
    // Two maps of overlapping planes, allocated in different orders (so the same corner has
    // different rows in each): every corner of `target` that `source` has gets its feature.
    for (const FeaturePrecision precision :
         {FeaturePrecision::kFloat32, FeaturePrecision::kFloat16}) {
        FeatureOctreeConfig config;
        config.leaf_size_m = 0.2;
        config.feature_precision = precision;
        FeatureOctree source(config);
        source.allocate_cells(plane_points(3.0f, 0.0f, 2.0f, 0.1f));
        source.allocate_cells(plane_points(0.0f, 0.0f, 4.0f, 0.1f));
        config.seed = 7;  // other initial features, so that a copy is seen
        FeatureOctree target(config);
        target.allocate_cells(plane_points(2.0f, 0.0f, 4.0f, 0.1f));
        const auto source_rows = all_rows(source);
        const auto target_rows = all_rows(target);
        const auto row_of = [&](const FeatureOctree& octree, std::int32_t row) {
            std::vector<float> values(static_cast<std::size_t>(config.feature_dim));
            octree.features().get_row(static_cast<std::size_t>(row), values.data());
            return values;
        };
        std::map<CornerKey, std::vector<float>> before;
        for (const auto& [key, row] : target_rows) before[key] = row_of(target, row);

        const std::size_t copied = target.copy_shared_features(source);
        std::size_t shared = 0, kept = 0;
        for (const auto& [key, row] : target_rows) {
            const auto in_source = source_rows.find(key);
            if (in_source != source_rows.end()) {
                ++shared;
                EXPECT_EQ(row_of(target, row), row_of(source, in_source->second));
            } else {
                ++kept;
                EXPECT_EQ(row_of(target, row), before[key]);
            }
        }
        // all_rows() lists the corners of complete cells, which are all the corners here.
        EXPECT_EQ(copied, shared);
        EXPECT_GT(shared, 100u);
        EXPECT_GT(kept, 100u) << "the target reaches past the source (x from 4 to 6 m)";
        std::size_t changed = 0;
        for (const auto& [key, row] : target_rows) changed += row_of(target, row) != before[key];
        EXPECT_GT(changed, 0u) << "the two maps' initial features differ";
    }
    FeatureOctreeConfig coarse;
    coarse.leaf_size_m = 0.4;
    FeatureOctree other(coarse);
    FeatureOctreeConfig fine;
    fine.leaf_size_m = 0.2;
    FeatureOctree target(fine);
    EXPECT_THROW(target.copy_shared_features(other), ConfigError);
}
