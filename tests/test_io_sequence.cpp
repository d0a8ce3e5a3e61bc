#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "shine/core/error.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/pcd.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/io/tum.hpp"

namespace fs = std::filesystem;

namespace {

fs::path test_dir(const std::string& name) {
    const fs::path dir = fs::path(SHINE_TEST_TMP_DIR) / "io_sequence" / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

void write_text(const fs::path& path, const std::string& text) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out << text;
    ASSERT_TRUE(out.good());
}

Eigen::Isometry3d make_pose(double yaw, const Eigen::Vector3d& t) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    T.translation() = t;
    return T;
}

std::vector<Eigen::Isometry3d> trajectory(int n) {
    std::vector<Eigen::Isometry3d> poses;
    for (int i = 0; i < n; ++i) poses.push_back(make_pose(0.1 * i, Eigen::Vector3d(i, 0.5 * i, 0)));
    return poses;
}

/// Scan i holds i + 1 points so a wrong scan is easy to spot.
std::vector<Eigen::Vector3f> scan_points(int i) {
    std::vector<Eigen::Vector3f> points;
    for (int k = 0; k <= i; ++k)
        points.emplace_back(static_cast<float>(i), static_cast<float>(k), 1.0f);
    return points;
}

/// KITTI layout with `scans` scans and `poses` poses.
fs::path make_kitti(const std::string& name, int scans, int poses) {
    const fs::path dir = test_dir(name);
    fs::create_directories(dir / "velodyne");
    for (int i = 0; i < scans; ++i) {
        char file[32];
        std::snprintf(file, sizeof(file), "%06d.bin", i);
        shine::write_kitti_bin(dir / "velodyne" / file, scan_points(i));
    }
    shine::write_kitti_poses(dir / "poses.txt", trajectory(poses));
    return dir;
}

constexpr double kPoseTolerance = 1e-12;

}  // namespace

TEST(ScanSequence, KittiLayoutWithoutCalibUsesPosesAsIs) {
    const fs::path dir = make_kitti("kitti_plain", 5, 5);
    const auto seq = shine::ScanSequence::open(dir);
    ASSERT_EQ(seq.size(), 5u);
    const auto poses = trajectory(5);
    for (std::size_t i = 0; i < 5; ++i) {
        EXPECT_TRUE(seq.pose(i).matrix().isApprox(poses[i].matrix(), kPoseTolerance)) << i;
        EXPECT_EQ(seq.scan_path(i).parent_path().filename(), "velodyne");
    }
    const shine::Scan scan = seq.load(3);
    EXPECT_EQ(scan.points_sensor, scan_points(3));
    EXPECT_EQ(scan.source, dir / "velodyne" / "000003.bin");
    EXPECT_TRUE(scan.T_world_sensor.matrix().isApprox(poses[3].matrix(), kPoseTolerance));
    EXPECT_EQ(seq.directory(), dir);
}

TEST(ScanSequence, KittiCalibTurnsCameraPosesIntoLidarPoses) {
    const fs::path dir = make_kitti("kitti_calib", 4, 4);
    // KITTI's Tr maps LiDAR (x forward, z up) into the camera frame (z forward, y down).
    Eigen::Isometry3d Tr = Eigen::Isometry3d::Identity();
    Tr.linear() << 0, -1, 0, 0, 0, -1, 1, 0, 0;
    Tr.translation() = Eigen::Vector3d(0.01, -0.08, -0.27);
    char line[512];
    std::snprintf(line, sizeof(line),
                  "P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: %.17g %.17g %.17g %.17g "
                  "%.17g %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n",
                  Tr(0, 0), Tr(0, 1), Tr(0, 2), Tr(0, 3), Tr(1, 0), Tr(1, 1), Tr(1, 2), Tr(1, 3),
                  Tr(2, 0), Tr(2, 1), Tr(2, 2), Tr(2, 3));
    write_text(dir / "calib.txt", line);
    const auto seq = shine::ScanSequence::open(dir);
    const auto camera_poses = trajectory(4);
    for (std::size_t i = 0; i < 4; ++i) {
        const Eigen::Isometry3d expected = Tr.inverse() * camera_poses[i] * Tr;
        EXPECT_TRUE(seq.pose(i).matrix().isApprox(expected.matrix(), kPoseTolerance)) << i;
    }
    // Pose 1's translation written out by hand: R_Tr^T (R_P t_Tr + t_P - t_Tr).
    const Eigen::Vector3d t1 = seq.pose(1).translation();
    const Eigen::Vector3d by_hand =
        Tr.linear().transpose() * (camera_poses[1].linear() * Tr.translation() +
                                   camera_poses[1].translation() - Tr.translation());
    EXPECT_TRUE(t1.isApprox(by_hand, kPoseTolerance)) << t1.transpose();
    EXPECT_FALSE(seq.pose(1).matrix().isApprox(camera_poses[1].matrix(), 1e-3));
}

TEST(ScanSequence, FewerPosesThanScansIsADataErrorNamingBothCounts) {
    const fs::path dir = make_kitti("too_few_poses", 5, 3);
    try {
        shine::ScanSequence::open(dir);
        FAIL() << "expected DataError";
    } catch (const shine::DataError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("has 3 poses"), std::string::npos) << msg;
        EXPECT_NE(msg.find("5 scans"), std::string::npos) << msg;
        EXPECT_NE(msg.find((dir / "poses.txt").string()), std::string::npos) << msg;
    }
}

TEST(ScanSequence, ExtraPosesAreIgnored) {
    const fs::path dir = make_kitti("extra_poses", 3, 7);
    const auto seq = shine::ScanSequence::open(dir);
    EXPECT_EQ(seq.size(), 3u);
}

TEST(ScanSequence, FrameRangeAndStep) {
    const fs::path dir = make_kitti("range", 6, 6);
    shine::ScanSequenceOptions options;
    options.first_frame = 1;
    options.last_frame = 4;
    options.frame_step = 2;
    const auto seq = shine::ScanSequence::open(dir, options);
    ASSERT_EQ(seq.size(), 2u);
    EXPECT_EQ(seq.scan_path(0).filename(), "000001.bin");
    EXPECT_EQ(seq.scan_path(1).filename(), "000003.bin");
    EXPECT_TRUE(seq.pose(1).matrix().isApprox(trajectory(6)[3].matrix(), kPoseTolerance));
    EXPECT_EQ(seq.load(1).points_sensor, scan_points(3));

    options.last_frame = 6;  // one past the end
    EXPECT_THROW(shine::ScanSequence::open(dir, options), shine::ConfigError);
    options.last_frame = -1;
    options.frame_step = 0;
    EXPECT_THROW(shine::ScanSequence::open(dir, options), shine::ConfigError);
    options.frame_step = 1;
    options.first_frame = 6;
    EXPECT_THROW(shine::ScanSequence::open(dir, options), shine::ConfigError);
    options.first_frame = 3;
    options.last_frame = 2;
    EXPECT_THROW(shine::ScanSequence::open(dir, options), shine::ConfigError);
}

TEST(ScanSequence, MissingOrEmptyDirectoryExplainsTheLayout) {
    const fs::path dir = test_dir("empty");
    for (const fs::path& path : {dir / "does_not_exist", dir}) {
        try {
            shine::ScanSequence::open(path);
            FAIL() << "expected IoError for " << path;
        } catch (const shine::IoError& e) {
            const std::string msg = e.what();
            EXPECT_NE(msg.find(path.string()), std::string::npos) << msg;
            EXPECT_NE(msg.find("velodyne/"), std::string::npos) << msg;
            EXPECT_NE(msg.find(".ply"), std::string::npos) << msg;
        }
    }
    // Scans but no pose file.
    fs::create_directories(dir / "velodyne");
    shine::write_kitti_bin(dir / "velodyne" / "000000.bin", scan_points(0));
    try {
        shine::ScanSequence::open(dir);
        FAIL() << "expected IoError";
    } catch (const shine::IoError& e) {
        EXPECT_NE(std::string(e.what()).find("poses.txt"), std::string::npos) << e.what();
    }
}

TEST(ScanSequence, PlyFolderInScansSubfolderWithTumPoses) {
    const fs::path dir = test_dir("ply_tum");
    fs::create_directories(dir / "scans");
    // Unpadded names: numeric order must win over string order ("10" after "9").
    const int kScans = 11;
    for (int i = 0; i < kScans; ++i) {
        shine::write_ply_points(dir / "scans" / (std::to_string(i) + ".ply"), scan_points(i));
    }
    // A reference mesh beside the scans must not be taken for a scan.
    shine::write_ply_mesh(dir / "gt_mesh.ply", shine::TriangleMesh{});
    std::vector<shine::StampedPose> stamped;
    const auto poses = trajectory(kScans);
    for (int i = 0; i < kScans; ++i) stamped.push_back({0.1 * i, poses[i]});
    shine::write_tum_poses(dir / "poses_tum.txt", stamped);
    // A calib.txt applies to KITTI-format poses only; this one must be ignored.
    write_text(dir / "calib.txt", "Tr: 0 -1 0 0 0 0 -1 0 1 0 0 0\n");

    const auto seq = shine::ScanSequence::open(dir);
    ASSERT_EQ(seq.size(), static_cast<std::size_t>(kScans));
    for (int i = 0; i < kScans; ++i) {
        EXPECT_EQ(seq.scan_path(i).filename(), std::to_string(i) + ".ply");
        EXPECT_TRUE(seq.pose(i).matrix().isApprox(poses[i].matrix(), 1e-12)) << i;
    }
    EXPECT_EQ(seq.load(10).points_sensor, scan_points(10));
}

TEST(ScanSequence, PcdFolderWithExplicitPoseFileAndFormat) {
    const fs::path dir = test_dir("pcd_explicit");
    for (int i = 0; i < 3; ++i) {
        char file[32];
        std::snprintf(file, sizeof(file), "cloud_%03d.pcd", i);
        shine::write_pcd_points(dir / file, scan_points(i));
    }
    const fs::path pose_file = dir / "trajectory.txt";
    std::vector<shine::StampedPose> stamped;
    for (const auto& T : trajectory(3)) stamped.push_back({0.0, T});
    shine::write_tum_poses(pose_file, stamped);

    shine::ScanSequenceOptions options;
    options.poses_path = pose_file;
    options.pose_format = "tum";
    const auto seq = shine::ScanSequence::open(dir, options);
    ASSERT_EQ(seq.size(), 3u);
    EXPECT_EQ(seq.load(2).points_sensor, scan_points(2));
    EXPECT_TRUE(seq.pose(2).matrix().isApprox(trajectory(3)[2].matrix(), 1e-12));

    // Auto-detection sniffs the 8-field lines (and the '#' header) as TUM too.
    options.pose_format = "auto";
    EXPECT_EQ(shine::ScanSequence::open(dir, options).size(), 3u);
    // Read as KITTI, the same file is an IoError naming the pose file.
    options.pose_format = "kitti";
    try {
        shine::ScanSequence::open(dir, options);
        FAIL() << "expected IoError";
    } catch (const shine::IoError& e) {
        EXPECT_NE(std::string(e.what()).find("trajectory.txt"), std::string::npos) << e.what();
    }
    options.pose_format = "quaternions";
    EXPECT_THROW(shine::ScanSequence::open(dir, options), shine::ConfigError);
}

TEST(ScanSequence, LoadReportsACorruptScan) {
    const fs::path dir = make_kitti("corrupt_scan", 3, 3);
    write_text(dir / "velodyne" / "000001.bin", "12345");
    const auto seq = shine::ScanSequence::open(dir);  // scans are read lazily
    EXPECT_EQ(seq.load(0).points_sensor.size(), 1u);
    try {
        seq.load(1);
        FAIL() << "expected IoError";
    } catch (const shine::IoError& e) {
        EXPECT_NE(std::string(e.what()).find("000001.bin"), std::string::npos) << e.what();
    }
}

TEST(ScanSequence, EmptyBinIsAScanWithoutPoints) {
    const fs::path dir = make_kitti("empty_scan", 3, 3);
    shine::write_kitti_bin(dir / "velodyne" / "000001.bin", {});
    const auto seq = shine::ScanSequence::open(dir);
    ASSERT_EQ(seq.size(), 3u);
    EXPECT_TRUE(seq.load(1).points_sensor.empty());
    EXPECT_EQ(seq.load(2).points_sensor, scan_points(2));
}

TEST(ScanSequence, PosesIfPresentOpensADirectoryWithoutPosesAtIdentity) {
    const fs::path dir = make_kitti("poses_if_present", 4, 4);
    shine::ScanSequenceOptions options;
    options.poses = shine::PoseFileUse::kIfPresent;
    // With a pose file it is read as usual.
    const auto with_file = shine::ScanSequence::open(dir, options);
    EXPECT_TRUE(with_file.has_poses());
    EXPECT_TRUE(with_file.pose(2).matrix().isApprox(trajectory(4)[2].matrix(), kPoseTolerance));
    // Without one: identity poses, has_poses() false, frame selection still applies.
    fs::remove(dir / "poses.txt");
    EXPECT_THROW(shine::ScanSequence::open(dir), shine::IoError);
    options.frame_step = 2;
    const auto without = shine::ScanSequence::open(dir, options);
    EXPECT_FALSE(without.has_poses());
    ASSERT_EQ(without.size(), 2u);
    EXPECT_TRUE(without.pose(1).isApprox(Eigen::Isometry3d::Identity()));
    EXPECT_EQ(without.load(1).points_sensor, scan_points(2));
    EXPECT_FALSE(without.subset({1}).has_poses());
    // Poses given afterwards (batch mapping on estimated poses).
    const auto placed = without.with_poses(trajectory(2));
    EXPECT_TRUE(placed.has_poses());
    EXPECT_TRUE(placed.load(1).T_world_sensor.isApprox(trajectory(2)[1]));
    EXPECT_EQ(placed.load(1).points_sensor, scan_points(2));
    EXPECT_THROW(without.with_poses(trajectory(3)), shine::DataError);
}
