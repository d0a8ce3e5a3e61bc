// End to end through the `shine` executable: simulated scans -> map -> surface -> mesh -> F-score,
// and bad input that must fail with a clear message and leave no output behind.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include "cli_test_support.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {

// Measured on this configuration (6 frames, seed 3, 0.2 m leaves, 1500 iterations): F-score
// 0.907 at 10 cm; the bound leaves room for other machines' floating-point differences.
constexpr double kMinFscore = 0.85;

fs::path test_dir() { return test_dir_of("cli"); }

CliResult run(const std::string& args) { return run_shine(args, test_dir()); }

// A small simulated street (made once per test process).
const fs::path& street() {
    static const fs::path dir = [] {
        const fs::path d = test_dir() / "street";
        simulate_street(d, /*frames=*/6, /*seed=*/3);
        return d;
    }();
    return dir;
}

fs::path copy_of_street(const std::string& name) {
    const fs::path d = test_dir() / name;
    fs::remove_all(d);
    fs::create_directories(d / "velodyne");
    for (const auto& e : fs::directory_iterator(street() / "velodyne")) {
        fs::copy_file(e.path(), d / "velodyne" / e.path().filename());
    }
    fs::copy_file(street() / "poses.txt", d / "poses.txt");
    return d;
}

void expect_no_outputs(const fs::path& out) {
    for (const char* f : {"map.vdb", "surface.vdb", "mesh.ply", "stats.json"}) {
        EXPECT_FALSE(fs::exists(out / f)) << f << " was written despite the error";
    }
}

}  // namespace

TEST(EndToEnd, SimulatedStreetMapsToAnAccurateMesh) {
    const fs::path out = test_dir() / "out";
    fs::remove_all(out);
    const CliResult r = run("map " + street().string() + " -o " + out.string() +
                            " --iterations 1500 --threads 2 -q");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    for (const char* f : {"map.vdb", "surface.vdb", "mesh.ply", "stats.json"}) {
        EXPECT_TRUE(fs::exists(out / f)) << f;
    }
    std::ifstream in(out / "stats.json");
    const nlohmann::json stats = nlohmann::json::parse(in);
    const double fscore = stats.at("eval").at("fscore").get<double>();
    std::printf("F-score at 10 cm: %.4f, map %.2f MB\n", fscore,
                stats.at("map").at("map_bytes").get<double>() / 1e6);
    EXPECT_GT(fscore, kMinFscore);
    EXPECT_EQ(stats.at("frames").get<int>(), 6);

    // The saved map re-bakes and re-meshes at another resolution.
    const CliResult m = run("mesh " + (out / "map.vdb").string() + " -o " +
                            (out / "coarse.ply").string() + " --voxel-size-m 0.2");
    ASSERT_EQ(m.exit_code, 0) << m.output;
    const CliResult e = run("eval --pred " + (out / "coarse.ply").string() + " --ref " +
                            (street() / "gt_mesh.ply").string() + " --json");
    ASSERT_EQ(e.exit_code, 0) << e.output;
    EXPECT_GT(nlohmann::json::parse(e.output).at("fscore").get<double>(), 0.5);
}

TEST(BadInput, MissingDirectory) {
    const fs::path out = test_dir() / "out_missing";
    fs::remove_all(out);
    const CliResult r =
        run("map " + (test_dir() / "no_such_dir").string() + " -o " + out.string() + " -q");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("no_such_dir"), std::string::npos) << r.output;
    expect_no_outputs(out);
}

TEST(BadInput, BinSizeNotMultipleOf16) {
    const fs::path data = copy_of_street("bad_bin");
    const fs::path bin = data / "velodyne" / "000002.bin";
    fs::resize_file(bin, fs::file_size(bin) - 3);
    const fs::path out = test_dir() / "out_bad_bin";
    fs::remove_all(out);
    const CliResult r = run("map " + data.string() + " -o " + out.string() + " -q --iterations 10");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("000002.bin"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("16"), std::string::npos) << r.output;
    expect_no_outputs(out);
}

TEST(BadInput, FewerPosesThanScans) {
    const fs::path data = copy_of_street("few_poses");
    {
        std::ifstream in(data / "poses.txt");
        std::string line, kept;
        for (int i = 0; i < 4 && std::getline(in, line); ++i) kept += line + "\n";
        in.close();
        std::ofstream(data / "poses.txt") << kept;
    }
    const fs::path out = test_dir() / "out_few_poses";
    fs::remove_all(out);
    const CliResult r = run("map " + data.string() + " -o " + out.string() + " -q --iterations 10");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("poses.txt"), std::string::npos) << r.output;
    expect_no_outputs(out);
}

namespace {

// Writes a NaN/inf point over point 100 of `bin` (a sensor's "no return").
void inject_non_finite_point(const fs::path& bin) {
    std::fstream f(bin, std::ios::in | std::ios::out | std::ios::binary);
    const float bad[4] = {std::numeric_limits<float>::quiet_NaN(), 1.0f,
                          std::numeric_limits<float>::infinity(), 0.0f};
    f.seekp(16 * 100);
    f.write(reinterpret_cast<const char*>(bad), sizeof(bad));
}

// Replaces the points of `bin` by `count` invalid ones (NaN, infinite and zero-range).
void write_invalid_scan(const fs::path& bin, int count) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    std::ofstream f(bin, std::ios::binary | std::ios::trunc);
    for (int i = 0; i < count; ++i) {
        const float point[4] = {i % 3 == 0 ? nan : 0.0f, i % 3 == 1 ? -inf : 0.0f, 0.0f, 0.0f};
        f.write(reinterpret_cast<const char*>(point), sizeof(point));
    }
}

}  // namespace

TEST(BadInput, NonFinitePointsAreDroppedAndCounted) {
    const fs::path data = copy_of_street("nan_points");
    inject_non_finite_point(data / "velodyne" / "000001.bin");
    // A scan with only invalid points, and an empty scan (a sensor that returned nothing).
    write_invalid_scan(data / "velodyne" / "000003.bin", 1000);
    std::ofstream(data / "velodyne" / "000004.bin", std::ios::binary | std::ios::trunc).close();
    const fs::path out = test_dir() / "out_nan";
    fs::remove_all(out);
    const CliResult r = run("map " + data.string() + " -o " + out.string() + " -q --iterations 10");
    ASSERT_EQ(r.exit_code, 0) << r.output;
    std::ifstream in(out / "stats.json");
    const nlohmann::json stats = nlohmann::json::parse(in);
    EXPECT_EQ(stats.at("frames").get<int>(), 6);
    // 1 injected + 2 of every 3 in the invalid scan are non-finite; the rest are zero-range.
    EXPECT_EQ(stats.at("preprocess").at("dropped_nonfinite").get<int>(), 1 + 667);
    EXPECT_GE(stats.at("preprocess").at("dropped_zero_range").get<int>(), 333);
}

TEST(BadInput, NonFinitePointsFailUnderTheErrorPolicy) {
    const fs::path data = copy_of_street("nan_points_error");
    inject_non_finite_point(data / "velodyne" / "000001.bin");
    const fs::path config = test_dir() / "invalid_points_error.yaml";
    std::ofstream(config) << "preprocess:\n  invalid_points: error\n";
    const fs::path out = test_dir() / "out_nan_error";
    fs::remove_all(out);
    const CliResult r = run("map " + data.string() + " -o " + out.string() + " -c " +
                            config.string() + " -q --iterations 10");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("000001.bin"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("point 100"), std::string::npos) << r.output;
    expect_no_outputs(out);
}

TEST(BadInput, SequenceWithoutAnyValidPoint) {
    const fs::path data = copy_of_street("no_valid_points");
    int scan = 0;
    for (const auto& e : fs::directory_iterator(data / "velodyne")) {
        // Half the scans empty, half holding only invalid points.
        if (scan++ % 2 == 0) {
            std::ofstream(e.path(), std::ios::binary | std::ios::trunc).close();
        } else {
            write_invalid_scan(e.path(), 10);
        }
    }
    const fs::path out = test_dir() / "out_no_valid_points";
    fs::remove_all(out);
    const CliResult r = run("map " + data.string() + " -o " + out.string() + " -q --iterations 10");
    EXPECT_NE(r.exit_code, 0);
    EXPECT_EQ(r.output.find("internal error"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("no points left"), std::string::npos) << r.output;
    expect_no_outputs(out);
}

TEST(BadInput, UnreadableVdb) {
    const fs::path garbage = test_dir() / "garbage.vdb";
    std::ofstream(garbage) << "not an OpenVDB file at all";
    const fs::path mesh = test_dir() / "garbage_mesh.ply";
    fs::remove(mesh);
    const CliResult r = run("mesh " + garbage.string() + " -o " + mesh.string());
    EXPECT_NE(r.exit_code, 0);
    EXPECT_NE(r.output.find("garbage.vdb"), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("internal error"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(mesh));
    const CliResult b = run("bake " + garbage.string() + " -o " + (test_dir() / "g.vdb").string());
    EXPECT_NE(b.exit_code, 0);
    EXPECT_NE(b.output.find("garbage.vdb"), std::string::npos) << b.output;
}
