#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <string_view>

#include "shine/core/error.hpp"
#include "shine/io/kitti.hpp"

namespace fs = std::filesystem;

namespace {

fs::path test_dir(const std::string& name) {
    const fs::path dir = fs::path(SHINE_TEST_TMP_DIR) / "io_kitti" / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

void write_bytes(const fs::path& path, const std::string& bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
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

std::vector<Eigen::Isometry3d> random_poses(int n, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<Eigen::Isometry3d> poses;
    for (int i = 0; i < n; ++i) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        T.linear() =
            Eigen::AngleAxisd(3.0 * u(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized())
                .toRotationMatrix();
        T.translation() = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 1234.5678901;
        poses.push_back(T);
    }
    return poses;
}

const char* kIdentityLine = "1 0 0 0 0 1 0 0 0 0 1 0\n";

}  // namespace

TEST(KittiBin, RoundTripIsExactAndIntensityIsZero) {
    const fs::path path = test_dir("bin_roundtrip") / "000000.bin";
    std::vector<Eigen::Vector3f> points;
    std::mt19937 rng(3);
    std::normal_distribution<float> g(0.0f, 30.0f);
    for (int i = 0; i < 5000; ++i) points.emplace_back(g(rng), g(rng), g(rng));
    shine::write_kitti_bin(path, points);
    EXPECT_EQ(fs::file_size(path), points.size() * 16);
    EXPECT_EQ(shine::read_kitti_bin(path), points);
    std::ifstream in(path, std::ios::binary);
    float record[4];
    in.read(reinterpret_cast<char*>(record), sizeof(record));
    EXPECT_EQ(record[0], points[0].x());
    EXPECT_EQ(record[3], 0.0f);
}

TEST(KittiBin, ReadsHandMadeFileWithItsIntensityColumn) {
    const fs::path path = test_dir("bin_hand") / "scan.bin";
    const float data[12] = {1.5f,  -2.0f, 3.25f, 0.7f, 10.0f, 20.0f,
                            30.0f, 99.0f, 4.0f,  5.0f, 6.0f,  0.0f};
    write_bytes(path, std::string(reinterpret_cast<const char*>(data), sizeof(data)));
    const auto points = shine::read_kitti_bin(path);
    ASSERT_EQ(points.size(), 3u);
    EXPECT_EQ(points[0], Eigen::Vector3f(1.5f, -2.0f, 3.25f));
    EXPECT_EQ(points[1], Eigen::Vector3f(10.0f, 20.0f, 30.0f));
    std::vector<float> intensity;
    EXPECT_EQ(shine::read_kitti_bin(path, &intensity), points);
    EXPECT_EQ(intensity, (std::vector<float>{0.7f, 99.0f, 0.0f}));  // as stored, zero included
}

TEST(KittiBin, IntensityRoundTripsAndAllZeroOrNanColumnsMeanNone) {
    const fs::path dir = test_dir("bin_intensity");
    const std::vector<Eigen::Vector3f> points = {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}};
    std::vector<float> intensity;
    // Given intensities, NaN among them (its point is kept), come back bit for bit.
    const float nan = std::numeric_limits<float>::quiet_NaN();
    shine::write_kitti_bin(dir / "a.bin", points, {0.25f, nan, 1e-30f});
    EXPECT_EQ(shine::read_kitti_bin(dir / "a.bin", &intensity), points);
    ASSERT_EQ(intensity.size(), 3u);
    EXPECT_EQ(intensity[0], 0.25f);
    EXPECT_TRUE(std::isnan(intensity[1]));
    EXPECT_EQ(intensity[2], 1e-30f);  // one tiny non-zero value is a measurement
    // Written without intensity (0), or holding nothing but zeros and NaN: none.
    shine::write_kitti_bin(dir / "b.bin", points);
    intensity = {1.0f};
    shine::read_kitti_bin(dir / "b.bin", &intensity);
    EXPECT_TRUE(intensity.empty());
    shine::write_kitti_bin(dir / "c.bin", points, {0.0f, nan, -0.0f});
    shine::read_kitti_bin(dir / "c.bin", &intensity);
    EXPECT_TRUE(intensity.empty());
    // One intensity per point or none: anything else names the file.
    try {
        shine::write_kitti_bin(dir / "d.bin", points, {1.0f, 2.0f});
        FAIL() << "expected DataError";
    } catch (const shine::DataError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("d.bin"), std::string::npos) << m;
        EXPECT_NE(m.find("3 points but 2 intensities"), std::string::npos) << m;
    }
    EXPECT_FALSE(fs::exists(dir / "d.bin"));
}

TEST(KittiBin, ErrorsNameTheFileAndTheByteOffset) {
    const fs::path dir = test_dir("bin_errors");
    expect_io_error([&] { shine::read_kitti_bin(dir / "missing.bin"); }, dir / "missing.bin",
                    "does not exist");
    // 40 bytes: two whole points, then 8 bytes of a third starting at byte 32.
    write_bytes(dir / "odd.bin", std::string(40, '\0'));
    expect_io_error([&] { shine::read_kitti_bin(dir / "odd.bin"); }, dir / "odd.bin",
                    "byte offset 32: size 40 bytes is not a multiple of 16");
    expect_io_error([&] { shine::read_kitti_bin(dir / "odd.bin"); }, dir / "odd.bin",
                    "the last record has only 8 bytes");
    write_bytes(dir / "tiny.bin", "abc");
    expect_io_error([&] { shine::read_kitti_bin(dir / "tiny.bin"); }, dir / "tiny.bin",
                    "byte offset 0");
    expect_io_error([&] { shine::read_kitti_bin(dir); }, dir, "directory");
}

TEST(KittiBin, EmptyFileIsAScanWithoutPoints) {
    // A sensor may return nothing (blocked, spinning up): valid data, not an error.
    const fs::path path = test_dir("bin_empty") / "000000.bin";
    write_bytes(path, "");
    EXPECT_TRUE(shine::read_kitti_bin(path).empty());
    shine::write_kitti_bin(path, {});
    EXPECT_EQ(fs::file_size(path), 0u);
    EXPECT_TRUE(shine::read_kitti_bin(path).empty());
}

TEST(KittiBin, NonFinitePointsAreReturnedAsStored) {
    // Filtering NaN and infinite points is preprocess_scan's job; the reader must not hide them.
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    const float data[8] = {nan, 1.0f, 2.0f, 0.0f, 0.0f, -inf, 0.0f, 0.0f};
    const auto points = shine::parse_kitti_bin(
        std::string_view(reinterpret_cast<const char*>(data), sizeof(data)), "mem.bin");
    ASSERT_EQ(points.size(), 2u);
    EXPECT_TRUE(std::isnan(points[0].x()));
    EXPECT_EQ(points[1].y(), -inf);
}

TEST(KittiPoses, RoundTripKeepsFullPrecision) {
    const fs::path path = test_dir("poses_roundtrip") / "poses.txt";
    const auto poses = random_poses(50, 11);
    shine::write_kitti_poses(path, poses);
    const auto back = shine::read_kitti_poses(path);
    ASSERT_EQ(back.size(), poses.size());
    for (std::size_t i = 0; i < poses.size(); ++i) {
        // %.17g round-trips doubles exactly.
        EXPECT_TRUE((back[i].matrix().array() == poses[i].matrix().array()).all()) << i;
    }
}

TEST(KittiPoses, AcceptsBlankLinesCrlfAndSigns) {
    const fs::path path = test_dir("poses_format") / "poses.txt";
    write_bytes(path,
                "\n1 0 0 +1.5 0 1 0 -2e3 0 0 1 0.25\r\n   \n"
                "0 -1 0 0 1 0 0 0 0 0 1 7\n");
    const auto poses = shine::read_kitti_poses(path);
    ASSERT_EQ(poses.size(), 2u);
    EXPECT_EQ(poses[0].translation(), Eigen::Vector3d(1.5, -2000.0, 0.25));
    EXPECT_EQ(poses[1].linear()(0, 1), -1.0);
    EXPECT_EQ(poses[1].translation().z(), 7.0);
}

TEST(KittiPoses, ErrorsNameFileAndLine) {
    const fs::path dir = test_dir("poses_errors");
    write_bytes(dir / "count.txt", std::string(kIdentityLine) + "1 0 0 0 0 1 0 0 0 0 1\n");
    expect_io_error([&] { shine::read_kitti_poses(dir / "count.txt"); }, dir / "count.txt",
                    "line 2: expected 12 numbers");
    write_bytes(dir / "word.txt",
                std::string(kIdentityLine) + kIdentityLine + "1 0 0 0 0 1 0 0 0 0 1 1.0x\n");
    expect_io_error([&] { shine::read_kitti_poses(dir / "word.txt"); }, dir / "word.txt",
                    "line 3: '1.0x' is not a number");
    write_bytes(dir / "nan.txt", "1 0 0 nan 0 1 0 0 0 0 1 0\n");
    expect_io_error([&] { shine::read_kitti_poses(dir / "nan.txt"); }, dir / "nan.txt",
                    "line 1: contains a non-finite value");
    write_bytes(dir / "scaled.txt", "2 0 0 0 0 2 0 0 0 0 2 0\n");
    expect_io_error([&] { shine::read_kitti_poses(dir / "scaled.txt"); }, dir / "scaled.txt",
                    "not orthonormal");
    write_bytes(dir / "mirror.txt", "-1 0 0 0 0 1 0 0 0 0 1 0\n");
    expect_io_error([&] { shine::read_kitti_poses(dir / "mirror.txt"); }, dir / "mirror.txt",
                    "not orthonormal");
    write_bytes(dir / "tum.txt", "0.1 1 2 3 0 0 0 1\n");
    expect_io_error([&] { shine::read_kitti_poses(dir / "tum.txt"); }, dir / "tum.txt", "TUM");
    write_bytes(dir / "empty.txt", "");
    expect_io_error([&] { shine::read_kitti_poses(dir / "empty.txt"); }, dir / "empty.txt",
                    "empty");
    write_bytes(dir / "blank.txt", "\n  \n");
    expect_io_error([&] { shine::read_kitti_poses(dir / "blank.txt"); }, dir / "blank.txt",
                    "no poses (2 blank lines)");
    write_bytes(dir / "inf.txt", std::string(kIdentityLine) + "1 0 0 0 0 1 0 -inf 0 0 1 0\n");
    expect_io_error([&] { shine::read_kitti_poses(dir / "inf.txt"); }, dir / "inf.txt",
                    "line 2: contains a non-finite value");
    expect_io_error([&] { shine::read_kitti_poses(dir / "missing.txt"); }, dir / "missing.txt",
                    "does not exist");
}

TEST(KittiPoses, GarbageGivesAShortPrintableMessage) {
    const fs::path dir = test_dir("poses_garbage");
    // A binary file passed as poses: one 1 MB "word" of non-ASCII bytes and no blank or newline.
    std::string garbage;
    for (int i = 0; i < (1 << 20); ++i) garbage += static_cast<char>(0x80 + i % 128);
    garbage[0] = '\x7f';
    write_bytes(dir / "garbage.txt", garbage);
    try {
        shine::read_kitti_poses(dir / "garbage.txt");
        FAIL() << "expected IoError";
    } catch (const shine::IoError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("line 1: '\\x7f\\x81\\x82"), std::string::npos) << msg;
        EXPECT_NE(msg.find("...' is not a number"), std::string::npos) << msg;
        EXPECT_LT(msg.size(), 400u) << "the message quotes the whole line";
    }
}

TEST(KittiPoses, ParsesTextInMemory) {
    const auto poses = shine::parse_kitti_poses(kIdentityLine, "memory");
    ASSERT_EQ(poses.size(), 1u);
    EXPECT_TRUE(poses[0].matrix().isIdentity());
    try {
        shine::parse_kitti_poses("", "memory");
        FAIL() << "expected IoError";
    } catch (const shine::IoError& e) {
        EXPECT_NE(std::string(e.what()).find("'memory'"), std::string::npos) << e.what();
    }
}

TEST(KittiCalib, ReadsTrAmongProjectionMatrices) {
    const fs::path path = test_dir("calib") / "calib.txt";
    const Eigen::Isometry3d Tr = random_poses(1, 5)[0];
    std::string text =
        "P0: 7.188560e+02 0 6.071928e+02 0 0 7.188560e+02 1.852157e+02 0 0 0 1 0\n"
        "P1: 7.188560e+02 0 6.071928e+02 -3.861448e+02 0 7.188560e+02 1.852157e+02 0 0 0 1 0\n"
        "Tr:";
    char number[32];
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) {
            std::snprintf(number, sizeof(number), " %.17g", Tr.matrix()(r, c));
            text += number;
        }
    }
    text += "\n";
    write_bytes(path, text);
    const Eigen::Isometry3d back = shine::read_kitti_calib_tr(path);
    EXPECT_TRUE((back.matrix().array() == Tr.matrix().array()).all());
}

TEST(KittiCalib, ErrorsNameFileAndLine) {
    const fs::path dir = test_dir("calib_errors");
    write_bytes(dir / "no_tr.txt", "P0: 1 0 0 0 0 1 0 0 0 0 1 0\n");
    expect_io_error([&] { shine::read_kitti_calib_tr(dir / "no_tr.txt"); }, dir / "no_tr.txt",
                    "no 'Tr:' line");
    write_bytes(dir / "short_tr.txt", "P0: 1 0 0 0 0 1 0 0 0 0 1 0\nTr: 1 0 0 0 0 1 0 0\n");
    expect_io_error([&] { shine::read_kitti_calib_tr(dir / "short_tr.txt"); }, dir / "short_tr.txt",
                    "line 2");
    expect_io_error([&] { shine::read_kitti_calib_tr(dir / "missing.txt"); }, dir / "missing.txt",
                    "does not exist");
    write_bytes(dir / "two_tr.txt",
                std::string("Tr: ") + kIdentityLine + "Tr_velo_to_cam: " + kIdentityLine);
    expect_io_error([&] { shine::read_kitti_calib_tr(dir / "two_tr.txt"); }, dir / "two_tr.txt",
                    "line 2: second Tr line");
    write_bytes(dir / "word_tr.txt", "P0: 1\nP1: 2\nTr: 1 0 0 0 0 1 0 0 0 0 1 zero\n");
    expect_io_error([&] { shine::read_kitti_calib_tr(dir / "word_tr.txt"); }, dir / "word_tr.txt",
                    "line 3: 'zero' is not a number");
    write_bytes(dir / "skew_tr.txt", "Tr: 1 0 0 0 0.5 1 0 0 0 0 1 0\n");
    expect_io_error([&] { shine::read_kitti_calib_tr(dir / "skew_tr.txt"); }, dir / "skew_tr.txt",
                    "line 1: rotation is not orthonormal");
    write_bytes(dir / "empty.txt", "");
    expect_io_error([&] { shine::read_kitti_calib_tr(dir / "empty.txt"); }, dir / "empty.txt",
                    "empty");
    write_bytes(dir / "three_lines.txt", "a\nb\nc\n");
    expect_io_error([&] { shine::read_kitti_calib_tr(dir / "three_lines.txt"); },
                    dir / "three_lines.txt", "no 'Tr:' line among its 3 lines");
}

TEST(KittiCalib, AcceptsBlanksAroundTheKey) {
    const Eigen::Isometry3d Tr =
        shine::parse_kitti_calib_tr("  Tr : 1 0 0 5 0 1 0 6 0 0 1 7\r\n", "calib.txt");
    EXPECT_EQ(Tr.translation(), Eigen::Vector3d(5, 6, 7));
}
