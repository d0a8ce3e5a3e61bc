// End to end: `shine eval` on PLY files written to disk (needs the `shine` executable built).
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

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

}  // namespace
}  // namespace shine
