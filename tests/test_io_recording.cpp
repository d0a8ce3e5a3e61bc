// Recording readers (ROS 1 bag, ROS 2 SQLite bag, MCAP), PointCloud2 decoding and poses matched
// by time. The recordings are written by tests/recordings/write_recordings.py: ROS 1 bags by
// Debian's python3-rosbag (an independent writer), SQLite bags by python3's sqlite3 module,
// MCAP files by that script from the published specification; every reader must give back the
// KITTI scans they were made from, bit for bit.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <tuple>

#include "shine/core/error.hpp"
#include "shine/io/kitti.hpp"
#include "shine/io/mcap_reader.hpp"
#include "shine/io/point_cloud2.hpp"
#include "shine/io/pose_interpolation.hpp"
#include "shine/io/recording.hpp"
#include "shine/io/rosbag1_reader.hpp"
#include "shine/io/rosbag2_sqlite_reader.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/io/tum.hpp"

namespace shine {
namespace {
namespace fs = std::filesystem;

constexpr int kFrames = 6;
constexpr int kPointsPerScan = 301;  // odd: the SQLite fixture pads its organised cloud with NaN
constexpr double kStamp0S = 1700000000.0;
constexpr double kFramePeriodS = 0.1;

const fs::path kWriter = fs::path(__FILE__).parent_path() / "recordings" / "write_recordings.py";

std::string read_all(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

void write_all(const fs::path& path, const std::string& bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// A small KITTI folder and its recordings, written once per test process.
class Recordings : public ::testing::Test {
  protected:
    static void SetUpTestSuite() {
        writer_available_ = std::system(
                                "/usr/bin/python3 -c 'import rosbag, sensor_msgs, lz4, zstandard' "
                                ">/dev/null 2>&1") == 0;
        if (!writer_available_) return;
        // ctest runs every test in its own process, in parallel: one fixture folder per process.
        root_ = fs::path(SHINE_TEST_TMP_DIR) / ("io_recording_" + std::to_string(::getpid()));
        fs::remove_all(root_);
        fs::create_directories(root_ / "kitti" / "velodyne");
        std::mt19937 rng(7);
        std::uniform_real_distribution<float> coord(-20.0f, 20.0f);
        std::vector<Eigen::Isometry3d> poses;
        scans_.clear();
        for (int f = 0; f < kFrames; ++f) {
            std::vector<Eigen::Vector3f> points;
            std::vector<float> intensity;
            for (int i = 0; i < kPointsPerScan; ++i) {
                points.emplace_back(coord(rng), coord(rng), coord(rng) * 0.1f);
                // Whole numbers 0..255 (zeros among them): the uint8 and uint16 intensity fields
                // of the MCAP and SQLite fixtures hold them exactly.
                intensity.push_back(static_cast<float>((37 * f + 11 * i) % 256));
            }
            char name[32];
            std::snprintf(name, sizeof(name), "%06d.bin", f);
            write_kitti_bin(root_ / "kitti" / "velodyne" / name, points, intensity);
            scans_.push_back(points);
            intensities_.push_back(intensity);
            Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
            T.linear() = Eigen::AngleAxisd(0.1 * f, Eigen::Vector3d::UnitZ()).toRotationMatrix();
            T.translation() = Eigen::Vector3d(1.5 * f, 0.2 * f, 0.0);
            poses.push_back(T);
        }
        write_kitti_poses(root_ / "kitti" / "poses.txt", poses);
        const std::string command = "/usr/bin/python3 '" + kWriter.string() + "' '" +
                                    (root_ / "kitti").string() + "' '" + (root_ / "rec").string() +
                                    "' > '" + (root_ / "writer.log").string() + "' 2>&1";
        writer_ok_ = std::system(command.c_str()) == 0;
    }

    static void TearDownTestSuite() {
        std::error_code ec;
        if (!root_.empty()) fs::remove_all(root_, ec);
    }

    void SetUp() override {
        if (!writer_available_) {
            GTEST_SKIP() << "python3-rosbag, python3-sensor-msgs, python3-lz4 or "
                            "python3-zstandard is missing (scripts/setup.sh installs them)";
        }
        ASSERT_TRUE(writer_ok_) << read_all(root_ / "writer.log");
    }

    static fs::path rec(const std::string& name) { return root_ / "rec" / name; }

    static ScanSequenceOptions with_poses() {
        ScanSequenceOptions options;
        options.poses_path = rec("poses.tum");
        return options;
    }

    /// Every scan of `path` equals the KITTI scan it was written from (NaN pads aside), with the
    /// stamp and pose of the TUM file.
    static void expect_same_scans(const fs::path& path, bool has_nan_pad,
                                  const std::string& intensity_field) {
        const ScanSequence seq = ScanSequence::open(path, with_poses());
        ASSERT_EQ(seq.size(), static_cast<std::size_t>(kFrames));
        const std::vector<StampedPose> tum = read_tum_poses(rec("poses.tum"));
        for (int f = 0; f < kFrames; ++f) {
            const Scan scan = seq.load(static_cast<std::size_t>(f));
            const auto& expected = scans_[static_cast<std::size_t>(f)];
            ASSERT_EQ(scan.points_sensor.size(), expected.size() + (has_nan_pad ? 1 : 0));
            for (std::size_t i = 0; i < expected.size(); ++i) {
                ASSERT_EQ(scan.points_sensor[i], expected[i]) << path << " frame " << f;
            }
            if (has_nan_pad) {
                EXPECT_TRUE(std::isnan(scan.points_sensor.back().x()));
            }
            // Each fixture names the intensity differently (float32, uint16, uint8); every one
            // gives the KITTI column back exactly.
            EXPECT_EQ(scan.intensity_field, intensity_field);
            ASSERT_EQ(scan.intensity.size(), scan.points_sensor.size());
            for (std::size_t i = 0; i < expected.size(); ++i) {
                ASSERT_EQ(scan.intensity[i], intensities_[static_cast<std::size_t>(f)][i])
                    << path << " frame " << f << " point " << i;
            }
            EXPECT_NEAR(scan.stamp_s, kStamp0S + kFramePeriodS * f, kPoseStampToleranceS);
            // Stamps at pose times take the pose exactly (no interpolation arithmetic).
            EXPECT_TRUE(scan.T_world_sensor.matrix() ==
                        tum[static_cast<std::size_t>(f)].T_world_sensor.matrix());
            // Every fixture carries per-point times spread over 0.1 s, relative to the stamp.
            ASSERT_EQ(scan.point_time_s.size(), scan.points_sensor.size());
            constexpr double kTimeToleranceS = 1e-6;  // float32 seconds / absolute float64
            EXPECT_NEAR(scan.point_time_s[0], 0.0, kTimeToleranceS);
            const double last = 0.1 * (kPointsPerScan - 1) / kPointsPerScan;
            EXPECT_NEAR(scan.point_time_s[expected.size() - 1], last, kTimeToleranceS);
        }
    }

    static inline bool writer_available_ = false;
    static inline bool writer_ok_ = false;
    static inline fs::path root_;
    static inline std::vector<std::vector<Eigen::Vector3f>> scans_;
    static inline std::vector<std::vector<float>> intensities_;
};

TEST_F(Recordings, Ros1BagsUncompressedBz2Lz4GiveTheKittiScans) {
    for (const char* name : {"street.bag", "street_bz2.bag", "street_lz4.bag"}) {
        SCOPED_TRACE(name);
        expect_same_scans(rec(name), false, "intensity");
    }
}

TEST_F(Recordings, Ros2SqliteBagGivesTheKittiScans) {
    expect_same_scans(rec("street_db3"), true, "reflectivity");
    // A bare .db3 file too.
    expect_same_scans(rec("street_db3") / "street_db3_0.db3", true, "reflectivity");
}

TEST_F(Recordings, McapBagOfTwoFilesAndBareMcapGiveTheKittiScans) {
    expect_same_scans(rec("street_mcap"), false, "i");
    expect_same_scans(rec("street.mcap"), false, "i");
}

TEST_F(Recordings, KittiFolderKeepsItsIntensityColumn) {
    ScanSequenceOptions options;
    const ScanSequence seq = ScanSequence::open(root_ / "kitti", options);
    for (int f = 0; f < kFrames; ++f) {
        const Scan scan = seq.load(static_cast<std::size_t>(f));
        EXPECT_EQ(scan.intensity, intensities_[static_cast<std::size_t>(f)]) << f;
        EXPECT_EQ(scan.intensity_field, "4th column");
    }
}

TEST_F(Recordings, TopicsListTypesAndCounts) {
    const auto reader = open_recording(rec("street_db3"));
    const std::vector<RecordingTopic> topics = reader->topics();
    ASSERT_EQ(topics.size(), 2u);
    EXPECT_EQ(topics[0].name, "/points");
    EXPECT_EQ(topics[0].type, "sensor_msgs/msg/PointCloud2");
    EXPECT_EQ(topics[0].message_count, static_cast<std::size_t>(kFrames));
    EXPECT_EQ(topics[1].message_count, 0u);
    EXPECT_EQ(select_point_cloud_topic(*reader, "").name, "/points");
}

TEST_F(Recordings, FrameSelectionWorksOnMessages) {
    ScanSequenceOptions options = with_poses();
    options.first_frame = 1;
    options.last_frame = 5;
    options.frame_step = 2;
    const ScanSequence seq = ScanSequence::open(rec("street_lz4.bag"), options);
    ASSERT_EQ(seq.size(), 3u);
    EXPECT_EQ(seq.load(1).points_sensor.front(), scans_[3].front());
    EXPECT_NEAR(seq.stamp_s(2), kStamp0S + 5 * kFramePeriodS, kPoseStampToleranceS);
}

TEST_F(Recordings, SeveralPointCloudTopicsNeedTopicAndAreListed) {
    try {
        ScanSequence::open(rec("two_topics.bag"), with_poses());
        FAIL() << "expected DataError";
    } catch (const DataError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("two_topics.bag"), std::string::npos) << m;
        EXPECT_NE(m.find("--topic"), std::string::npos) << m;
        EXPECT_NE(m.find("/points_b  sensor_msgs/PointCloud2  2 messages"), std::string::npos) << m;
    }
    ScanSequenceOptions options = with_poses();
    options.topic = "/points_b";
    EXPECT_EQ(ScanSequence::open(rec("two_topics.bag"), options).size(), 2u);
    options.topic = "/nope";
    try {
        ScanSequence::open(rec("two_topics.bag"), options);
        FAIL() << "expected DataError";
    } catch (const DataError& e) {
        EXPECT_NE(std::string(e.what()).find("no topic '/nope'"), std::string::npos) << e.what();
    }
}

TEST_F(Recordings, RecordingOfAnotherMessageTypeIsRejected) {
    try {
        ScanSequence::open(rec("strings.bag"), with_poses());
        FAIL() << "expected DataError";
    } catch (const DataError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("strings.bag"), std::string::npos) << m;
        EXPECT_NE(m.find("no sensor_msgs/PointCloud2"), std::string::npos) << m;
        EXPECT_NE(m.find("/chatter  std_msgs/String  3 messages"), std::string::npos) << m;
    }
}

TEST_F(Recordings, PointCloudWithoutZIsRejectedNamingTheFile) {
    // Opening decodes the first message, so the layout problem stops a run before any output.
    try {
        ScanSequence::open(rec("no_z.bag"), with_poses());
        FAIL() << "expected DataError";
    } catch (const DataError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("no_z.bag"), std::string::npos) << m;
        EXPECT_NE(m.find("x, y and z"), std::string::npos) << m;
        EXPECT_NE(m.find("fields: x y intensity ring t"), std::string::npos) << m;
    }
}

TEST_F(Recordings, WithoutPosesTheMessageAsksForAPoseFile) {
    try {
        ScanSequence::open(rec("street.bag"));
        FAIL() << "expected ConfigError";
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("--poses FILE"), std::string::npos) << e.what();
    }
}

TEST_F(Recordings, KittiPosesHaveNoTimesAndAreRefused) {
    ScanSequenceOptions options;
    options.poses_path = root_ / "kitti" / "poses.txt";
    try {
        ScanSequence::open(rec("street.bag"), options);
        FAIL() << "expected ConfigError";
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("give a TUM trajectory"), std::string::npos)
            << e.what();
    }
}

TEST_F(Recordings, ScanOutsideThePoseSpanIsAnErrorNamingTheStamp) {
    // The first 3 poses only: scans 3..5 are after the trajectory.
    const std::string text = read_all(rec("poses.tum"));
    std::size_t pos = 0;
    for (int line = 0; line < 4; ++line) pos = text.find('\n', pos) + 1;  // comment + 3 poses
    const fs::path short_poses = root_ / "short.tum";
    write_all(short_poses, text.substr(0, pos));
    ScanSequenceOptions options;
    options.poses_path = short_poses;
    try {
        ScanSequence::open(rec("street.mcap"), options);
        FAIL() << "expected DataError";
    } catch (const DataError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("stamped 1700000000.300000 s"), std::string::npos) << m;
        EXPECT_NE(m.find("outside the time span"), std::string::npos) << m;
    }
}

/// Damaged copies of each format: every one ends in a shine::Error naming the file.
TEST_F(Recordings, EmptyTruncatedAndCorruptRecordingsNameTheFile) {
    const fs::path dir = root_ / "damaged";
    fs::create_directories(dir);
    struct Case {
        std::string name;
        std::string bytes;
    };
    std::vector<Case> cases;
    for (const char* ext : {".bag", ".mcap", ".db3"})
        cases.push_back({std::string("empty") + ext, ""});
    const std::string bag = read_all(rec("street_bz2.bag"));
    const std::string lz4 = read_all(rec("street_lz4.bag"));
    const std::string mcap = read_all(rec("street_mcap") / "street_mcap_0.mcap");
    const std::string db3 = read_all(rec("street_db3") / "street_db3_0.db3");
    for (const std::string* src : {&bag, &lz4, &mcap, &db3}) {
        ASSERT_GT(src->size(), 8192u);
    }
    cases.push_back({"truncated.bag", bag.substr(0, bag.size() / 2)});
    cases.push_back({"truncated.mcap", mcap.substr(0, mcap.size() / 2)});
    cases.push_back({"truncated.db3", db3.substr(0, 4096)});
    // Corrupt: bytes in the middle of the compressed chunk data overwritten.
    const auto corrupt = [](std::string s) {
        for (std::size_t i = s.size() / 2; i < s.size() / 2 + 64; ++i) s[i] = '\x55';
        return s;
    };
    cases.push_back({"corrupt_bz2.bag", corrupt(bag)});
    cases.push_back({"corrupt_lz4.bag", corrupt(lz4)});
    cases.push_back({"corrupt.mcap", corrupt(mcap)});
    std::string db3_bad = db3;
    for (std::size_t i = 100; i < 4096 && i < db3_bad.size(); ++i) db3_bad[i] = '\x55';
    cases.push_back({"corrupt.db3", db3_bad});
    cases.push_back({"not_a_bag.bag", "this is text, not a recording\n"});
    for (const Case& c : cases) {
        SCOPED_TRACE(c.name);
        const fs::path path = dir / c.name;
        write_all(path, c.bytes);
        try {
            const ScanSequence seq = ScanSequence::open(path, with_poses());
            for (std::size_t i = 0; i < seq.size(); ++i) seq.load(i);
            ADD_FAILURE() << "no error for " << c.name;
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find(c.name), std::string::npos) << e.what();
        }
    }
}

// --- Without the fixture writer ---------------------------------------------------------------

TEST(PointCloud2, EncodeDecodeRoundTripsBothEncodings) {
    PointCloud2Scan scan;
    scan.stamp_s = 12.25;
    scan.frame_id = "lidar";
    scan.points_sensor = {{1.f, 2.f, 3.f}, {-4.5f, 5.f, NAN}};
    scan.point_time_s = {0.0, 0.05};
    for (MessageEncoding enc : {MessageEncoding::kCdr, MessageEncoding::kRos1}) {
        const PointCloud2Scan back =
            decode_point_cloud2(encode_point_cloud2(scan, enc), enc, "memory");
        EXPECT_EQ(back.stamp_s, 12.25);
        EXPECT_EQ(back.frame_id, "lidar");
        ASSERT_EQ(back.points_sensor.size(), 2u);
        EXPECT_EQ(back.points_sensor[0], scan.points_sensor[0]);
        EXPECT_TRUE(std::isnan(back.points_sensor[1].z()));  // kept: preprocess_scan drops it
        EXPECT_EQ(back.point_time_s, scan.point_time_s);
        EXPECT_EQ(back.time_field, "t");
        EXPECT_EQ(decode_header_stamp_s(encode_point_cloud2(scan, enc), enc, "memory"), 12.25);
        // Without intensities the encoder pads the field with 0, which reads as none.
        EXPECT_TRUE(back.intensity.empty());
        EXPECT_EQ(back.intensity_field, "");
    }
    // Given intensities go into the field and come back, NaN included (its point is kept).
    scan.intensity = {41.5f, NAN};
    for (MessageEncoding enc : {MessageEncoding::kCdr, MessageEncoding::kRos1}) {
        const PointCloud2Scan back =
            decode_point_cloud2(encode_point_cloud2(scan, enc), enc, "memory");
        ASSERT_EQ(back.intensity.size(), 2u);
        EXPECT_EQ(back.intensity[0], 41.5f);
        EXPECT_TRUE(std::isnan(back.intensity[1]));
        EXPECT_EQ(back.intensity_field, "intensity");
    }
    scan.intensity = {1.0f};  // not one per point
    EXPECT_THROW(encode_point_cloud2(scan, MessageEncoding::kCdr), DataError);
}

/// A ROS 1 PointCloud2 of one point at (1, 2, 3) with the fields `extra` after x y z, laid out by
/// hand per sensor_msgs/PointCloud2 (seq, stamp, frame_id, height, width, fields, is_bigendian,
/// point_step, row_step, data, is_dense): the bytes of `extra_data` follow x y z in the point.
std::string ros1_cloud_with(
    const std::vector<std::tuple<std::string, std::uint8_t, std::uint32_t>>& extra,
    const std::string& extra_data) {
    std::string m;
    const auto u32 = [&m](std::uint32_t v) { m.append(reinterpret_cast<const char*>(&v), 4); };
    const auto str = [&](const std::string& s) {
        u32(static_cast<std::uint32_t>(s.size()));
        m += s;
    };
    u32(0);  // seq
    u32(7);  // stamp.sec
    u32(0);  // stamp.nsec
    str("lidar");
    u32(1);  // height
    u32(1);  // width
    u32(static_cast<std::uint32_t>(3 + extra.size()));
    std::uint32_t offset = 0;
    for (const char* axis : {"x", "y", "z"}) {
        str(axis);
        u32(offset);
        m += static_cast<char>(7);  // FLOAT32
        u32(1);
        offset += 4;
    }
    std::uint32_t extra_offset = offset;
    for (const auto& [name, datatype, count] : extra) {
        str(name);
        u32(extra_offset);
        m += static_cast<char>(datatype);
        u32(count);
        extra_offset += datatype == 8 ? 8 : (datatype >= 5 ? 4 : (datatype >= 3 ? 2 : 1));
    }
    const std::uint32_t point_step = 12 + static_cast<std::uint32_t>(extra_data.size());
    m += '\0';  // is_bigendian
    u32(point_step);
    u32(point_step);  // row_step
    std::string data(12, '\0');
    const float xyz[3] = {1.0f, 2.0f, 3.0f};
    std::memcpy(data.data(), xyz, 12);
    data += extra_data;
    str(data);
    m += '\1';  // is_dense
    return m;
}

TEST(PointCloud2, IntensityFieldsOfEveryTypeInOrderOfPreference) {
    const auto decode = [](const std::string& message) {
        return decode_point_cloud2(message, MessageEncoding::kRos1, "bag 'x.bag', message 0");
    };
    // int16 -7, and a uint8 `i` after it: `reflectivity` comes before `i`.
    std::string bytes;
    const std::int16_t minus_seven = -7;
    bytes.append(reinterpret_cast<const char*>(&minus_seven), 2);
    bytes += static_cast<char>(200);
    PointCloud2Scan scan = decode(ros1_cloud_with({{"Reflectivity", 3, 1}, {"i", 2, 1}}, bytes));
    ASSERT_EQ(scan.intensity.size(), 1u);
    EXPECT_EQ(scan.intensity[0], -7.0f);
    EXPECT_EQ(scan.intensity_field, "Reflectivity");
    // The uint8 alone: as stored, not rescaled to 0..1.
    scan = decode(ros1_cloud_with({{"ring", 4, 1}, {"i", 2, 1}}, std::string("\0\0", 2) + "\xc8"));
    ASSERT_EQ(scan.intensity.size(), 1u);
    EXPECT_EQ(scan.intensity[0], 200.0f);
    // uint32 and float64 `intensity` win over `reflectivity`.
    const std::uint32_t big = 4000000000u;
    std::string u32_bytes(reinterpret_cast<const char*>(&big), 4);
    scan = decode(ros1_cloud_with({{"reflectivity", 2, 1}, {"intensity", 6, 1}},
                                  std::string("\x05", 1) + u32_bytes));
    EXPECT_EQ(scan.intensity, std::vector<float>{4e9f});
    const double precise = 0.1234567890123;
    scan = decode(ros1_cloud_with({{"intensity", 8, 1}},
                                  std::string(reinterpret_cast<const char*>(&precise), 8)));
    EXPECT_EQ(scan.intensity, std::vector<float>{static_cast<float>(precise)});
    // No intensity field: none.
    scan = decode(ros1_cloud_with({{"ring", 4, 1}}, std::string("\1\0", 2)));
    EXPECT_TRUE(scan.intensity.empty());
    // An unknown datatype or a count other than 1 is a DataError naming the message.
    for (const auto& [datatype, count] :
         {std::pair<std::uint8_t, std::uint32_t>{9, 1}, {7, 0}, {7, 3}}) {
        try {
            decode(ros1_cloud_with({{"intensity", datatype, count}}, std::string(12, '\0')));
            ADD_FAILURE() << "expected DataError for datatype " << int(datatype) << " count "
                          << count;
        } catch (const DataError& e) {
            const std::string m = e.what();
            EXPECT_NE(m.find("x.bag"), std::string::npos) << m;
            EXPECT_NE(m.find("intensity field 'intensity'"), std::string::npos) << m;
        }
    }
}

TEST(PointCloud2, BigEndianIsRejectedClearly) {
    PointCloud2Scan scan;
    scan.points_sensor = {{1.f, 2.f, 3.f}};
    std::string cdr = encode_point_cloud2(scan, MessageEncoding::kCdr);
    std::string be = cdr;
    be[1] = 0x00;  // CDR_BE encapsulation
    EXPECT_THROW(
        {
            try {
                decode_point_cloud2(be, MessageEncoding::kCdr, "msg");
            } catch (const IoError& e) {
                EXPECT_NE(std::string(e.what()).find("big-endian"), std::string::npos);
                throw;
            }
        },
        IoError);
    // is_bigendian = true: the byte after the last field (count 1) of the 4 fields.
    std::string ros1 = encode_point_cloud2(scan, MessageEncoding::kRos1);
    const std::size_t flag = ros1.size() - 1 - 16 - 4 - 4 - 4 - 1;  // is_dense, data, steps
    ASSERT_EQ(ros1[flag], 0);
    ros1[flag] = 1;
    try {
        decode_point_cloud2(ros1, MessageEncoding::kRos1, "msg");
        FAIL() << "expected IoError";
    } catch (const IoError& e) {
        EXPECT_NE(std::string(e.what()).find("is_bigendian"), std::string::npos) << e.what();
    }
}

TEST(PointCloud2, EveryTruncationIsAnIoError) {
    PointCloud2Scan scan;
    scan.points_sensor = {{1.f, 2.f, 3.f}, {4.f, 5.f, 6.f}};
    scan.point_time_s = {0.0, 0.1};
    for (MessageEncoding enc : {MessageEncoding::kCdr, MessageEncoding::kRos1}) {
        const std::string full = encode_point_cloud2(scan, enc);
        for (std::size_t n = 0; n + 1 < full.size(); ++n) {
            EXPECT_THROW(decode_point_cloud2(full.substr(0, n), enc, "msg"), IoError) << n;
        }
    }
}

TEST(PoseInterpolation, ExactAtPosesLinearAndSlerpBetweenErrorOutside) {
    std::vector<StampedPose> poses(2);
    poses[0].timestamp_s = 10.0;
    poses[1].timestamp_s = 11.0;
    poses[1].T_world_sensor.translation() = Eigen::Vector3d(2.0, 0.0, 0.0);
    poses[1].T_world_sensor.linear() =
        Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    check_pose_times(poses, "p.tum");
    EXPECT_TRUE(interpolate_pose(poses, 11.0, "p.tum").matrix() ==
                poses[1].T_world_sensor.matrix());
    const Eigen::Isometry3d mid = interpolate_pose(poses, 10.25, "p.tum");
    constexpr double kTolerance = 1e-12;
    EXPECT_NEAR(mid.translation().x(), 0.5, kTolerance);
    EXPECT_NEAR(Eigen::AngleAxisd(mid.rotation()).angle(), 0.25, kTolerance);
    EXPECT_THROW(interpolate_pose(poses, 9.9, "p.tum"), DataError);
    EXPECT_THROW(interpolate_pose(poses, 11.1, "p.tum"), DataError);
    std::swap(poses[0], poses[1]);
    EXPECT_THROW(check_pose_times(poses, "p.tum"), DataError);
}

}  // namespace
}  // namespace shine
