#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <fstream>
#include <string>

#include "shine/core/error.hpp"
#include "shine/io/tum.hpp"

namespace fs = std::filesystem;

namespace {

fs::path test_dir(const std::string& name) {
    const fs::path dir = fs::path(SHINE_TEST_TMP_DIR) / "io_tum" / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

void write_text(const fs::path& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << text;
    ASSERT_TRUE(out.good());
}

template <typename F>
void expect_io_error(F&& f, const fs::path& path, const std::string& fragment) {
    try {
        f();
        ADD_FAILURE() << "expected IoError for " << path;
    } catch (const shine::IoError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find(path.filename().string()), std::string::npos) << msg;
        EXPECT_NE(msg.find(fragment), std::string::npos)
            << "missing '" << fragment << "' in: " << msg;
    }
}

constexpr double kRotationTolerance = 1e-12;

}  // namespace

TEST(TumPoses, ReadsCommentsAndNormalisesQuaternions) {
    const fs::path path = test_dir("read") / "poses.tum";
    // Second quaternion is (0, 0, sin 45°, cos 45°) scaled by 2: a 90° yaw after normalisation.
    write_text(path,
               "# timestamp tx ty tz qx qy qz qw\n"
               "\n"
               "1305031102.175304 1.5 -2 3 0 0 0 1\n"
               "1305031102.211214 0 0 1 0 0 1.4142135623730951 1.4142135623730951\n");
    const auto poses = shine::read_tum_poses(path);
    ASSERT_EQ(poses.size(), 2u);
    EXPECT_DOUBLE_EQ(poses[0].timestamp_s, 1305031102.175304);
    EXPECT_EQ(poses[0].T_world_sensor.translation(), Eigen::Vector3d(1.5, -2, 3));
    EXPECT_TRUE(poses[0].T_world_sensor.linear().isIdentity(kRotationTolerance));
    const Eigen::Vector3d x_rotated = poses[1].T_world_sensor.linear() * Eigen::Vector3d::UnitX();
    EXPECT_TRUE(x_rotated.isApprox(Eigen::Vector3d::UnitY(), kRotationTolerance)) << x_rotated;
    EXPECT_NEAR(poses[1].T_world_sensor.linear().determinant(), 1.0, kRotationTolerance);
}

TEST(TumPoses, RoundTrip) {
    const fs::path path = test_dir("roundtrip") / "poses_tum.txt";
    std::vector<shine::StampedPose> poses(3);
    for (int i = 0; i < 3; ++i) {
        poses[i].timestamp_s = 1e9 + 0.1 * i;
        poses[i].T_world_sensor.linear() =
            Eigen::AngleAxisd(0.3 * (i + 1), Eigen::Vector3d(1, 2, 3).normalized())
                .toRotationMatrix();
        poses[i].T_world_sensor.translation() = Eigen::Vector3d(i, -i * 0.125, 1.0 / 3.0);
    }
    shine::write_tum_poses(path, poses);
    const auto back = shine::read_tum_poses(path);
    ASSERT_EQ(back.size(), 3u);
    for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(back[i].timestamp_s, poses[i].timestamp_s);
        EXPECT_EQ(back[i].T_world_sensor.translation(), poses[i].T_world_sensor.translation());
        EXPECT_TRUE(back[i].T_world_sensor.linear().isApprox(poses[i].T_world_sensor.linear(),
                                                             kRotationTolerance));
    }
}

TEST(TumPoses, ErrorsNameFileAndLine) {
    const fs::path dir = test_dir("errors");
    write_text(dir / "zero.tum", "# c\n0 1 2 3 0 0 0 0\n");
    expect_io_error([&] { shine::read_tum_poses(dir / "zero.tum"); }, dir / "zero.tum",
                    "line 2: quaternion is zero");
    write_text(dir / "count.tum", "0 1 2 3 0 0 0 1\n1 1 2 3 0 0 1\n");
    expect_io_error([&] { shine::read_tum_poses(dir / "count.tum"); }, dir / "count.tum",
                    "line 2: expected 8 fields");
    write_text(dir / "word.tum", "0 1 2 3 0 0 zero 1\n");
    expect_io_error([&] { shine::read_tum_poses(dir / "word.tum"); }, dir / "word.tum",
                    "line 1: 'zero' is not a number");
    write_text(dir / "inf.tum", "0 1 inf 3 0 0 0 1\n");
    expect_io_error([&] { shine::read_tum_poses(dir / "inf.tum"); }, dir / "inf.tum", "non-finite");
    write_text(dir / "empty.tum", "");
    expect_io_error([&] { shine::read_tum_poses(dir / "empty.tum"); }, dir / "empty.tum", "empty");
    write_text(dir / "comments.tum", "# only\n# comments\n");
    expect_io_error([&] { shine::read_tum_poses(dir / "comments.tum"); }, dir / "comments.tum",
                    "no poses (2 comment or blank lines)");
    write_text(dir / "late_comment.tum", "0 1 2 3 0 0 0 1\n1 1 2 3 0 0 0 1 # moved\n");
    expect_io_error([&] { shine::read_tum_poses(dir / "late_comment.tum"); },
                    dir / "late_comment.tum", "line 2: comment after data");
    write_text(dir / "nine.tum", "\n\n0 1 2 3 0 0 0 1 7\n");
    expect_io_error([&] { shine::read_tum_poses(dir / "nine.tum"); }, dir / "nine.tum",
                    "line 3: expected 8 fields (t x y z qx qy qz qw), found 9");
    write_text(dir / "kitti.tum", "1 0 0 0 0 1 0 0 0 0 1 0\n");
    expect_io_error([&] { shine::read_tum_poses(dir / "kitti.tum"); }, dir / "kitti.tum",
                    "found 12 (a KITTI pose file? use pose_format kitti)");
    write_text(dir / "binary.tum", std::string("0 1 2 \x01\xff\x00z 0 0 0 1\n", 19));
    expect_io_error([&] { shine::read_tum_poses(dir / "binary.tum"); }, dir / "binary.tum",
                    "line 1: '\\x01\\xff\\x00z' is not a number");
    expect_io_error([&] { shine::read_tum_poses(dir / "missing.tum"); }, dir / "missing.tum",
                    "does not exist");
}

TEST(TumPoses, ParsesTextInMemory) {
    const auto poses = shine::parse_tum_poses("5.5 1 2 3 0 0 0 1", "memory");
    ASSERT_EQ(poses.size(), 1u);
    EXPECT_EQ(poses[0].timestamp_s, 5.5);
    EXPECT_EQ(poses[0].T_world_sensor.translation(), Eigen::Vector3d(1, 2, 3));
}
