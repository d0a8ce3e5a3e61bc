// End to end: `shine eval` on PLY files written to disk (needs the `shine` executable built).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "shine/geometry/triangle_mesh.hpp"
#include "shine/io/ply.hpp"

namespace shine {
namespace {

namespace fs = std::filesystem;

/// Output and exit status of a shell command (stderr merged into stdout).
struct CommandResult {
    std::string output;
    int exit_code = -1;
};

CommandResult run(const std::string& command) {
    CommandResult result;
    FILE* pipe = popen((command + " 2>&1").c_str(), "r");
    if (pipe == nullptr) return result;
    std::array<char, 4096> buffer{};
    while (fgets(buffer.data(), buffer.size(), pipe) != nullptr) result.output += buffer.data();
    const int status = pclose(pipe);
    result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return result;
}

/// A 2 m x 2 m square (two triangles) at height z_m.
TriangleMesh square(float z_m) {
    TriangleMesh mesh;
    mesh.vertices = {{0, 0, z_m}, {2, 0, z_m}, {2, 2, z_m}, {0, 2, z_m}};
    mesh.triangles = {{0, 1, 2}, {0, 2, 3}};
    return mesh;
}

class EvalCli : public ::testing::Test {
  protected:
    void SetUp() override {
        if (!fs::exists(SHINE_CLI_PATH)) GTEST_SKIP() << "build the shine target first";
        dir_ = fs::path(SHINE_TEST_TMP_DIR) / "eval_cli";
        fs::create_directories(dir_);
    }
    std::string cli() const { return std::string("'") + SHINE_CLI_PATH + "' eval "; }
    fs::path dir_;
};

TEST_F(EvalCli, JsonOfAShiftedSquare) {
    constexpr double kShiftM = 0.05;
    constexpr double kShiftTolM = 0.002;  // 2 mm: in-plane scatter of the 2 cm voxel centroids
    write_ply_mesh(dir_ / "ref.ply", square(0.0f));
    write_ply_mesh(dir_ / "pred.ply", square(static_cast<float>(kShiftM)));
    const auto result = run(cli() + "--pred '" + (dir_ / "pred.ply").string() + "' --ref '" +
                            (dir_ / "ref.ply").string() + "' --json");
    ASSERT_EQ(result.exit_code, 0) << result.output;
    const auto json = nlohmann::json::parse(result.output);
    EXPECT_NEAR(json.at("accuracy_m").get<double>(), kShiftM, kShiftTolM);
    EXPECT_NEAR(json.at("completion_m").get<double>(), kShiftM, kShiftTolM);
    EXPECT_EQ(json.at("fscore").get<double>(), 1.0);

    const auto strict = run(cli() + "--pred '" + (dir_ / "pred.ply").string() + "' --ref '" +
                            (dir_ / "ref.ply").string() + "' --threshold-m 0.02");
    ASSERT_EQ(strict.exit_code, 0) << strict.output;
    EXPECT_NE(strict.output.find("F-score               0.00 %"), std::string::npos)
        << strict.output;
    EXPECT_NE(strict.output.find("accuracy              5.0"), std::string::npos) << strict.output;
}

TEST_F(EvalCli, MissingFileIsAnErrorNamingIt) {
    write_ply_mesh(dir_ / "ref.ply", square(0.0f));
    const auto result = run(cli() + "--pred '" + (dir_ / "no_such.ply").string() + "' --ref '" +
                            (dir_ / "ref.ply").string() + "'");
    EXPECT_EQ(result.exit_code, 1);
    EXPECT_NE(result.output.find("no_such.ply"), std::string::npos) << result.output;
}

/// A KITTI folder of four scans over the plane z = 0 from 2 m up, every point on the plane.
fs::path write_plane_sequence(const fs::path& dir) {
    fs::create_directories(dir / "velodyne");
    std::FILE* poses = std::fopen((dir / "poses.txt").c_str(), "w");
    for (int scan = 0; scan < 4; ++scan) {
        std::vector<float> values;
        for (int i = 0; i < 500; ++i) {
            const double azimuth = 0.0125 * i, elevation = -0.15 - 0.002 * i;
            const double range_m = 2.0 / std::sin(-elevation);
            values.insert(values.end(),
                          {float(range_m * std::cos(elevation) * std::cos(azimuth)),
                           float(range_m * std::cos(elevation) * std::sin(azimuth)), -2.0f, 1.0f});
        }
        char name[32];
        std::snprintf(name, sizeof(name), "%06d.bin", scan);
        std::FILE* bin = std::fopen((dir / "velodyne" / name).c_str(), "wb");
        std::fwrite(values.data(), sizeof(float), values.size(), bin);
        std::fclose(bin);
        std::fprintf(poses, "1 0 0 %d 0 1 0 0 0 0 1 2\n", scan);
    }
    std::fclose(poses);
    return dir;
}

TEST_F(EvalCli, HeldoutScansOnTheirPlaneScoreEveryRayAndBadInputStops) {
    TriangleMesh plane;
    plane.vertices = {{-50, -50, 0}, {50, -50, 0}, {50, 50, 0}, {-50, 50, 0}};
    plane.triangles = {{0, 1, 2}, {0, 2, 3}};
    write_ply_mesh(dir_ / "plane.ply", plane);
    const fs::path seq = write_plane_sequence(dir_ / "plane_seq");
    const std::string pred = "--pred '" + (dir_ / "plane.ply").string() + "' ";
    const auto result = run(cli() + pred + "--heldout '" + seq.string() + "' --frames 1,3 --json");
    ASSERT_EQ(result.exit_code, 0) << result.output;
    const auto json = nlohmann::json::parse(result.output);
    EXPECT_EQ(json.at("total").at("rays").get<int>(), 1000);
    EXPECT_EQ(json.at("total").at("hit_ratio").get<double>(), 1.0);
    EXPECT_EQ(json.at("total").at("within_ratio").get<double>(), 1.0);
    EXPECT_LT(json.at("total").at("median_abs_error_m").get<double>(), 1e-4);
    ASSERT_EQ(json.at("scans").size(), 2u);
    EXPECT_EQ(json.at("scans")[1].at("frame").get<int>(), 3);
    // Raised 5 cm the plane still catches every ray, but only within a 10 cm threshold.
    TriangleMesh raised = plane;
    for (auto& v : raised.vertices) v.z() = 0.05f;
    write_ply_mesh(dir_ / "raised.ply", raised);
    const auto strict = run(cli() + "--pred '" + (dir_ / "raised.ply").string() + "' --heldout '" +
                            seq.string() + "' --holdout-every 2 --threshold-m 0.02 --json");
    ASSERT_EQ(strict.exit_code, 0) << strict.output;
    EXPECT_EQ(nlohmann::json::parse(strict.output).at("total").at("within_ratio").get<double>(),
              0.0);

    const auto out_of_range = run(cli() + pred + "--heldout '" + seq.string() + "' --frames 4");
    EXPECT_EQ(out_of_range.exit_code, 1);
    EXPECT_NE(out_of_range.output.find("'4' is outside the sequence of 4 scans"), std::string::npos)
        << out_of_range.output;
    std::FILE* short_poses = std::fopen((dir_ / "short_poses.txt").c_str(), "w");
    std::fprintf(short_poses, "1 0 0 0 0 1 0 0 0 0 1 2\n");
    std::fclose(short_poses);
    const auto short_result =
        run(cli() + pred + "--heldout '" + seq.string() + "' --frames 1 --poses '" +
            (dir_ / "short_poses.txt").string() + "'");
    EXPECT_EQ(short_result.exit_code, 1);
    EXPECT_NE(short_result.output.find("short_poses.txt"), std::string::npos)
        << short_result.output;
    std::FILE* not_a_mesh = std::fopen((dir_ / "map.vdb").c_str(), "w");
    std::fprintf(not_a_mesh, "not a mesh");
    std::fclose(not_a_mesh);
    const auto wrong_file = run(cli() + "--pred '" + (dir_ / "map.vdb").string() + "' --heldout '" +
                                seq.string() + "' --frames 1");
    EXPECT_EQ(wrong_file.exit_code, 1);
    EXPECT_NE(wrong_file.output.find("map.vdb"), std::string::npos) << wrong_file.output;
    const auto both = run(cli() + pred + "--ref '" + (dir_ / "plane.ply").string() +
                          "' --heldout '" + seq.string() + "' --frames 1");
    EXPECT_EQ(both.exit_code, 1);
    EXPECT_NE(both.output.find("either --ref"), std::string::npos) << both.output;
    const auto no_frames = run(cli() + pred + "--heldout '" + seq.string() + "'");
    EXPECT_EQ(no_frames.exit_code, 1);
    EXPECT_NE(no_frames.output.find("--frames"), std::string::npos) << no_frames.output;
}

}  // namespace
}  // namespace shine
