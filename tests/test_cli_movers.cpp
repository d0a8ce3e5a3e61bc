// `shine simulate --movers` writes the movers into simulation.json and keeps them out of
// gt_mesh.ply; `shine eval --movers` reports the ghost area.
#include <gtest/gtest.h>

#include <string>

#include "cli_test_support.hpp"
#include "shine/io/mover_tracks.hpp"
#include "shine/io/ply.hpp"

namespace shine::cli_test {
namespace {

TEST(CliMovers, SimulateWritesMoversAndAStaticReference) {
    const fs::path dir = test_dir_of("cli_movers");
    const fs::path still = dir / "still";
    const fs::path moving = dir / "moving";
    simulate_street(still, 6, 3);
    fs::remove_all(moving);
    const CliResult r = run_shine(
        "simulate -o '" + moving.string() + "' --frames 6 --seed 3 --movers 4 --no-progress", dir);
    ASSERT_EQ(r.exit_code, 0) << r.output;

    const nlohmann::json json = read_json(moving / "simulation.json");
    ASSERT_TRUE(json.contains("movers"));
    EXPECT_EQ(json["movers"]["list"].size(), 4u);
    EXPECT_EQ(json["movers"]["list"][0]["kind"], "car");
    EXPECT_EQ(json["movers"]["frame_period_s"], 0.1);
    EXPECT_FALSE(read_json(still / "simulation.json").contains("movers"));
    const MoverTracks tracks = read_mover_tracks(moving / "simulation.json");
    EXPECT_EQ(tracks.movers.size(), 4u);

    // The reference is the static street: the same triangles, fewer of them observed (movers
    // hide some).
    const TriangleMesh with = read_ply_mesh(moving / "gt_mesh.ply");
    const TriangleMesh without = read_ply_mesh(still / "gt_mesh.ply");
    EXPECT_EQ(with.vertices, without.vertices);
    EXPECT_EQ(with.triangles, without.triangles);
    EXPECT_NE(read_text(moving / "velodyne" / "000003.bin"),
              read_text(still / "velodyne" / "000003.bin"));

    // eval --movers: the static reference scored against itself has no ghosts.
    const CliResult e =
        run_shine("eval --pred '" + (moving / "gt_mesh.ply").string() + "' --ref '" +
                      (moving / "gt_mesh.ply").string() + "' --movers '" +
                      (moving / "simulation.json").string() + "' --json",
                  dir);
    ASSERT_EQ(e.exit_code, 0) << e.output;
    const nlohmann::json metrics = nlohmann::json::parse(e.output);
    EXPECT_EQ(metrics["ghost"]["ghost_area_m2"], 0.0);
    EXPECT_EQ(metrics["ghost"]["num_movers"], 4);

    // eval --movers on a sequence simulated without movers names the file and the fix.
    const CliResult bad = run_shine("eval --pred '" + (still / "gt_mesh.ply").string() +
                                        "' --ref '" + (still / "gt_mesh.ply").string() +
                                        "' --movers '" + (still / "simulation.json").string() + "'",
                                    dir);
    EXPECT_NE(bad.exit_code, 0);
    EXPECT_NE(bad.output.find("--movers N"), std::string::npos) << bad.output;

    // Tiles are for a reference mesh, and have a positive size.
    const CliResult zero_tile =
        run_shine("eval --pred '" + (still / "gt_mesh.ply").string() + "' --ref '" +
                      (still / "gt_mesh.ply").string() + "' --tile-m 0",
                  dir);
    EXPECT_NE(zero_tile.exit_code, 0);
    EXPECT_NE(zero_tile.output.find("--tile-m"), std::string::npos) << zero_tile.output;
    const CliResult heldout_tiles =
        run_shine("eval --pred '" + (still / "gt_mesh.ply").string() + "' --heldout '" +
                      still.string() + "' --frames 1 --tile-m 50",
                  dir);
    EXPECT_NE(heldout_tiles.exit_code, 0);
    EXPECT_NE(heldout_tiles.output.find("use it with --ref"), std::string::npos)
        << heldout_tiles.output;
}

}  // namespace
}  // namespace shine::cli_test
