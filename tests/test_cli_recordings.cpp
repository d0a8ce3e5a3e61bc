// Recordings through the `shine` executable: a simulated street written as a ROS 1 bag (by
// Debian's python3-rosbag), a ROS 2 SQLite bag and a ROS 2 MCAP bag (tests/recordings/
// write_recordings.py) maps to the same mesh, byte for byte, as the KITTI folder it came from
// with the same poses; `shine convert` gives the KITTI folder back; broken recordings end with a
// message naming the file, a non-zero exit and no output.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <utility>

#include "cli_test_support.hpp"
#include "shine/io/kitti.hpp"

namespace shine::cli_test {
namespace {

constexpr int kFrames = 6;
constexpr int kSeed = 5;
const fs::path kWriter = fs::path(__FILE__).parent_path() / "recordings" / "write_recordings.py";

class CliRecordings : public ::testing::Test {
  protected:
    static void SetUpTestSuite() {
        available_ = std::system(
                         "/usr/bin/python3 -c 'import rosbag, sensor_msgs, lz4, "
                         "zstandard' >/dev/null 2>&1") == 0;
        if (!available_) return;
        // ctest runs every test in its own process, in parallel: one fixture folder per process.
        root_ = fs::path(SHINE_TEST_TMP_DIR) / ("cli_recordings_" + std::to_string(::getpid()));
        fs::remove_all(root_);
        fs::create_directories(root_);
        const CliResult sim = run_shine("simulate -o '" + (root_ / "street").string() +
                                            "' --frames " + std::to_string(kFrames) + " --seed " +
                                            std::to_string(kSeed) + " --no-progress",
                                        root_);
        if (sim.exit_code != 0) {
            setup_error_ = sim.output;
            return;
        }
        // The simulator writes no intensity (0): give every point a whole number 0..255, which
        // the recordings' float32, uint16 and uint8 intensity fields all hold exactly.
        for (int f = 0; f < kFrames; ++f) {
            const fs::path bin = root_ / "street" / "velodyne" / scan_file(f);
            const std::vector<Eigen::Vector3f> points = read_kitti_bin(bin);
            std::vector<float> intensity(points.size());
            for (std::size_t i = 0; i < points.size(); ++i) {
                intensity[i] = static_cast<float>((7 * f + 13 * i) % 256);
            }
            write_kitti_bin(bin, points, intensity);
        }
        const std::string command = "/usr/bin/python3 '" + kWriter.string() + "' '" +
                                    (root_ / "street").string() + "' '" + (root_ / "rec").string() +
                                    "' > '" + (root_ / "writer.log").string() + "' 2>&1";
        if (std::system(command.c_str()) != 0) setup_error_ = read_text(root_ / "writer.log");
    }

    static void TearDownTestSuite() {
        std::error_code ec;
        if (!root_.empty()) fs::remove_all(root_, ec);
    }

    void SetUp() override {
        if (!available_) {
            GTEST_SKIP() << "python3-rosbag, python3-sensor-msgs, python3-lz4 or "
                            "python3-zstandard is missing (scripts/setup.sh installs them)";
        }
        ASSERT_TRUE(setup_error_.empty()) << setup_error_;
        dir_ = test_dir_of("cli_recordings");
        fs::remove_all(dir_);  // outputs of an earlier run would make the commands refuse
        fs::create_directories(dir_);
    }

    static fs::path rec(const std::string& name) { return root_ / "rec" / name; }
    static std::string scan_file(int f) {
        char name[32];
        std::snprintf(name, sizeof(name), "%06d.bin", f);
        return name;
    }
    static std::string poses() { return "--poses '" + rec("poses.tum").string() + "'"; }

    /// `shine map DATA` with few iterations; returns the mesh's bytes.
    std::string map_mesh(const fs::path& data, const std::string& name) {
        const fs::path out = dir_ / name;
        const CliResult r = run_shine("map '" + data.string() + "' -o '" + out.string() + "' " +
                                          poses() + " --iterations 40 --threads 2 -q --no-eval",
                                      dir_);
        EXPECT_EQ(r.exit_code, 0) << r.output;
        return read_text(out / "mesh.ply");
    }

    /// A command that must fail naming `expected` in its message and write nothing to `out`.
    void expect_failure(const std::string& args, const fs::path& out, const std::string& expected) {
        const CliResult r = run_shine(args, dir_);
        EXPECT_NE(r.exit_code, 0) << r.output;
        EXPECT_NE(r.output.find("shine: error: "), std::string::npos) << r.output;
        EXPECT_NE(r.output.find(expected), std::string::npos) << r.output;
        EXPECT_FALSE(fs::exists(out)) << args;
        EXPECT_FALSE(fs::exists(out.string() + ".partial")) << args;
    }

    static inline bool available_ = false;
    static inline std::string setup_error_;
    static inline fs::path root_;
    fs::path dir_;
};

TEST_F(CliRecordings, BagSqliteAndMcapMapToTheKittiMeshBitForBit) {
    const std::string kitti = map_mesh(root_ / "street", "kitti");
    ASSERT_GT(kitti.size(), 1000u);
    EXPECT_TRUE(map_mesh(rec("street_lz4.bag"), "bag") == kitti) << "ROS 1 bag";
    EXPECT_TRUE(map_mesh(rec("street_db3"), "db3") == kitti) << "ROS 2 SQLite bag";
    EXPECT_TRUE(map_mesh(rec("street_mcap"), "mcap") == kitti) << "ROS 2 MCAP bag";
}

TEST_F(CliRecordings, ConvertWritesTheKittiLayoutBack) {
    const fs::path out = dir_ / "converted";
    const CliResult r = run_shine(
        "convert '" + rec("street.bag").string() + "' -o '" + out.string() + "' " + poses(), dir_);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    // Points and intensities (the 4th column) byte for byte.
    for (int f = 0; f < kFrames; ++f) {
        const fs::path name = fs::path("velodyne") / scan_file(f);
        EXPECT_TRUE(read_text(out / name) == read_text(root_ / "street" / name)) << name;
    }
    EXPECT_NE(r.output.find("intensity of 6 of 6 scans (field 'intensity')"), std::string::npos)
        << r.output;
    const std::string times = read_text(out / "times.txt");
    EXPECT_EQ(times.substr(0, 21), "1700000000.000000000\n");
    EXPECT_TRUE(fs::exists(out / "poses.txt"));
    // Without poses: scans and times, and a hint that poses.txt needs --poses.
    const fs::path bare = dir_ / "bare";
    const CliResult r2 =
        run_shine("convert '" + rec("street.mcap").string() + "' -o '" + bare.string() + "'", dir_);
    ASSERT_EQ(r2.exit_code, 0) << r2.output;
    EXPECT_NE(r2.output.find("--poses FILE"), std::string::npos) << r2.output;
    EXPECT_EQ(read_text(bare / "times.txt"), times);
    EXPECT_FALSE(fs::exists(bare / "poses.txt"));
}

TEST_F(CliRecordings, ConvertKeepsIntensityFieldsOfEveryTypeInTheFourthColumn) {
    // uint16 `reflectivity` of organised clouds padded with a NaN point (dropped with its
    // intensity), and uint8 `i`: the KITTI scans come back byte for byte.
    for (const auto& [recording, field] :
         {std::pair<std::string, std::string>{"street_db3", "reflectivity"},
          {"street.mcap", "i"}}) {
        SCOPED_TRACE(recording);
        const fs::path out = dir_ / ("from_" + field);
        const CliResult r =
            run_shine("convert '" + rec(recording).string() + "' -o '" + out.string() + "'", dir_);
        ASSERT_EQ(r.exit_code, 0) << r.output;
        for (int f = 0; f < kFrames; ++f) {
            const fs::path name = fs::path("velodyne") / scan_file(f);
            EXPECT_TRUE(read_text(out / name) == read_text(root_ / "street" / name)) << name;
        }
        EXPECT_NE(r.output.find("(field '" + field + "')"), std::string::npos) << r.output;
    }
    // A sequence without intensity (the simulator's zeros) says so and writes zeros.
    const fs::path plain = dir_ / "plain";
    fs::create_directories(plain / "velodyne");
    const std::vector<Eigen::Vector3f> points = {{1.0f, 2.0f, 3.0f}, {4.0f, 5.0f, 6.0f}};
    write_kitti_bin(plain / "velodyne" / scan_file(0), points);
    write_kitti_poses(plain / "poses.txt", {Eigen::Isometry3d::Identity()});
    const fs::path out = dir_ / "plain_out";
    const CliResult r =
        run_shine("convert '" + plain.string() + "' -o '" + out.string() + "'", dir_);
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find("no intensity in the input"), std::string::npos) << r.output;
    EXPECT_TRUE(read_text(out / "velodyne" / scan_file(0)) ==
                read_text(plain / "velodyne" / scan_file(0)));
}

TEST_F(CliRecordings, BrokenRecordingsFailNamingTheFileWithoutOutput) {
    const std::string bag = read_text(rec("street.bag"));
    const fs::path truncated = dir_ / "truncated.bag";
    {
        std::ofstream out(truncated, std::ios::binary);
        out << bag.substr(0, bag.size() / 3);
    }
    const fs::path empty = dir_ / "empty.mcap";
    std::ofstream(empty).close();
    const fs::path out = dir_ / "out";
    for (const char* command : {"map", "convert"}) {
        SCOPED_TRACE(command);
        const std::string pre = std::string(command) + " ";
        expect_failure(pre + "'" + truncated.string() + "' -o '" + out.string() + "' " + poses(),
                       out, "truncated.bag");
        expect_failure(pre + "'" + empty.string() + "' -o '" + out.string() + "' " + poses(), out,
                       "empty.mcap' is empty");
        expect_failure(
            pre + "'" + rec("two_topics.bag").string() + "' -o '" + out.string() + "' " + poses(),
            out, "choose one with --topic NAME");
        expect_failure(pre + "'" + rec("street.bag").string() + "' --topic /nope -o '" +
                           out.string() + "' " + poses(),
                       out, "has no topic '/nope'");
        expect_failure(
            pre + "'" + rec("strings.bag").string() + "' -o '" + out.string() + "' " + poses(), out,
            "no sensor_msgs/PointCloud2 messages");
        expect_failure(
            pre + "'" + rec("no_z.bag").string() + "' -o '" + out.string() + "' " + poses(), out,
            "needs fields x, y and z");
    }
    expect_failure("map '" + rec("street.bag").string() + "' -o '" + out.string() + "'", out,
                   "--poses FILE");
    // A message cut short deep in the recording (the first one is fine, so opening succeeds):
    // the run stops naming the message and leaves no output directory behind.
    const fs::path damaged = dir_ / "damaged_db3";
    fs::copy(rec("street_db3"), damaged);
    const std::string cut = "/usr/bin/python3 -c \"import sqlite3; db = sqlite3.connect('" +
                            (damaged / "street_db3_0.db3").string() +
                            "'); db.execute('UPDATE messages SET data = substr(data, 1, 200) "
                            "WHERE id = 4'); db.commit()\"";
    ASSERT_EQ(std::system(cut.c_str()), 0);
    expect_failure("map '" + damaged.string() + "' -o '" + out.string() + "' " + poses(), out,
                   "topic /points, message 3");
}

}  // namespace
}  // namespace shine::cli_test
