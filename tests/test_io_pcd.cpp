#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "shine/core/error.hpp"
#include "shine/io/pcd.hpp"

namespace fs = std::filesystem;

namespace {

fs::path test_dir(const std::string& name) {
    const fs::path dir = fs::path(SHINE_TEST_TMP_DIR) / "io_pcd" / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

void write_bytes(const fs::path& path, const std::string& bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    ASSERT_TRUE(out.good());
}

template <typename T>
void put(std::string& out, T value) {
    out.append(reinterpret_cast<const char*>(&value), sizeof(T));
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

/// Literal-only LZF stream: runs of at most 32 bytes, each preceded by (length - 1).
std::string lzf_literals(const std::string& in) {
    std::string out;
    for (std::size_t i = 0; i < in.size(); i += 32) {
        const std::size_t n = std::min<std::size_t>(32, in.size() - i);
        out += static_cast<char>(n - 1);
        out.append(in, i, n);
    }
    return out;
}

/// Greedy LZF compressor with a brute-force match search: slow, but small and obviously right,
/// and it emits both short (length 3..8) and extended (length 9..264) back-references.
std::string lzf_compress(const std::string& in) {
    std::string out, literals;
    const auto flush = [&] {
        out += lzf_literals(literals);
        literals.clear();
    };
    std::size_t i = 0;
    while (i < in.size()) {
        std::size_t best_len = 0, best_dist = 0;
        for (std::size_t dist = 1; dist <= std::min<std::size_t>(i, 8192); ++dist) {
            std::size_t len = 0;
            while (i + len < in.size() && len < 264 && in[i + len] == in[i - dist + len]) ++len;
            if (len > best_len) {
                best_len = len;
                best_dist = dist;
            }
        }
        if (best_len < 3) {
            literals += in[i++];
            continue;
        }
        flush();
        const std::size_t code = best_len - 2;
        const std::size_t d = best_dist - 1;
        if (code < 7) {
            out += static_cast<char>((code << 5) | (d >> 8));
        } else {
            out += static_cast<char>((7 << 5) | (d >> 8));
            out += static_cast<char>(code - 7);
        }
        out += static_cast<char>(d & 0xff);
        i += best_len;
    }
    flush();
    return out;
}

std::vector<Eigen::Vector3f> random_points(int n, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-50.0f, 50.0f);
    std::vector<Eigen::Vector3f> points;
    for (int i = 0; i < n; ++i) points.emplace_back(u(rng), u(rng), u(rng));
    return points;
}

/// A binary_compressed PCD with fields "intensity x y z" (F4 each, x as F8) holding `points`.
std::string compressed_pcd(const std::vector<Eigen::Vector3f>& points, bool literal_only) {
    const std::size_t n = points.size();
    std::string soa;
    for (std::size_t i = 0; i < n; ++i) put<float>(soa, 7.0f);  // intensity: compresses well
    for (const auto& p : points) put<double>(soa, p.x());
    for (const auto& p : points) put<float>(soa, p.y());
    for (const auto& p : points) put<float>(soa, p.z());
    const std::string block = literal_only ? lzf_literals(soa) : lzf_compress(soa);
    std::string file =
        "# .PCD v0.7\nVERSION 0.7\nFIELDS intensity x y z\nSIZE 4 8 4 4\n"
        "TYPE F F F F\nCOUNT 1 1 1 1\nWIDTH " +
        std::to_string(n) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(n) +
        "\nDATA binary_compressed\n";
    put<std::uint32_t>(file, static_cast<std::uint32_t>(block.size()));
    put<std::uint32_t>(file, static_cast<std::uint32_t>(soa.size()));
    return file + block;
}

}  // namespace

TEST(Pcd, BinaryRoundTripIsExact) {
    const fs::path path = test_dir("roundtrip") / "scan.pcd";
    const auto points = random_points(2000, 1);
    shine::write_pcd_points(path, points);
    EXPECT_EQ(shine::read_pcd_points(path), points);
    shine::write_pcd_points(path, {});
    EXPECT_TRUE(shine::read_pcd_points(path).empty());
}

TEST(Pcd, AsciiWithFieldsInAnyOrderAndCounts) {
    const fs::path path = test_dir("ascii") / "scan.pcd";
    write_bytes(path,
                "# .PCD v0.7 - Point Cloud Data file format\r\n"
                "VERSION 0.7\r\n"
                "FIELDS intensity normal z x y\r\n"
                "SIZE 4 4 8 4 8\r\n"
                "TYPE U F F F F\r\n"
                "COUNT 1 3 1 1 1\r\n"
                "WIDTH 3\r\n"
                "HEIGHT 1\r\n"
                "POINTS 3\r\n"
                "DATA ascii\r\n"
                "5 0 0 1 3.5 1.25 -2\r\n"
                "6 0 0 1 -1e2 +4 0.5\r\n"
                "\r\n"
                "7 0 0 1 nan 0 0\r\n");
    const auto points = shine::read_pcd_points(path);
    ASSERT_EQ(points.size(), 3u);
    EXPECT_EQ(points[0], Eigen::Vector3f(1.25f, -2.0f, 3.5f));
    EXPECT_EQ(points[1], Eigen::Vector3f(4.0f, 0.5f, -100.0f));
    EXPECT_TRUE(std::isnan(points[2].z()));  // NaN is data; preprocess_scan decides its fate
    // The U4 intensity, as stored: one per point, the NaN point's too.
    const shine::TimedPoints scan = shine::read_pcd_scan(path);
    EXPECT_EQ(scan.intensity, (std::vector<float>{5.0f, 6.0f, 7.0f}));
    EXPECT_EQ(scan.intensity_field, "intensity");
}

TEST(Pcd, IntensityOfAnyTypeInBinaryPreferringIntensityThenReflectivityThenI) {
    const fs::path dir = test_dir("intensity");
    // x y z F4, `i` U1, `reflectivity` I2 (negative values stay), padding: reflectivity wins.
    std::string file =
        "VERSION 0.7\nFIELDS x y z i reflectivity _\nSIZE 4 4 4 1 2 1\nTYPE F F F U I U\n"
        "COUNT 1 1 1 1 1 1\nWIDTH 3\nHEIGHT 1\nPOINTS 3\nDATA binary\n";
    const std::int16_t reflectivity[3] = {-3, 0, 30000};
    for (int k = 0; k < 3; ++k) {
        put<float>(file, 1.0f + k);
        put<float>(file, 2.0f);
        put<float>(file, 3.0f);
        put<std::uint8_t>(file, static_cast<std::uint8_t>(250 + k));
        put<std::int16_t>(file, reflectivity[k]);
        file += '\xee';
    }
    write_bytes(dir / "two.pcd", file);
    shine::TimedPoints scan = shine::read_pcd_scan(dir / "two.pcd");
    ASSERT_EQ(scan.points_sensor.size(), 3u);
    EXPECT_EQ(scan.intensity, (std::vector<float>{-3.0f, 0.0f, 30000.0f}));
    EXPECT_EQ(scan.intensity_field, "reflectivity");
    // Without `reflectivity`, the U1 `i`, not rescaled.
    const std::string only_i =
        "VERSION 0.7\nFIELDS x y z i\nSIZE 4 4 4 1\nTYPE F F F U\n"
        "WIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3 255\n";
    scan = shine::parse_pcd_scan(only_i, "only_i.pcd");
    EXPECT_EQ(scan.intensity, std::vector<float>{255.0f});
    EXPECT_EQ(scan.intensity_field, "i");
    // All zero: none (what writers without intensity put there).
    const std::string zeros =
        "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\n"
        "WIDTH 2\nPOINTS 2\nDATA ascii\n1 2 3 0\n4 5 6 0\n";
    scan = shine::parse_pcd_scan(zeros, "zeros.pcd");
    EXPECT_EQ(scan.points_sensor.size(), 2u);
    EXPECT_TRUE(scan.intensity.empty());
    EXPECT_EQ(scan.intensity_field, "");
}

TEST(PcdErrors, IntensityFieldsOfAnUnusableShapeNameFileAndLine) {
    const fs::path dir = test_dir("intensity_errors");
    write_bytes(dir / "count.pcd",
                "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\n"
                "COUNT 1 1 1 2\nWIDTH 1\nDATA ascii\n1 2 3 4 5\n");
    expect_io_error([&] { shine::read_pcd_scan(dir / "count.pcd"); }, dir / "count.pcd",
                    "line 5: intensity field 'intensity' has COUNT 2");
    write_bytes(dir / "half.pcd",
                "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 2\nTYPE F F F F\n"
                "WIDTH 1\nDATA ascii\n1 2 3 4\n");
    expect_io_error([&] { shine::read_pcd_scan(dir / "half.pcd"); }, dir / "half.pcd",
                    "line 3: intensity field 'intensity' is TYPE F with SIZE 2");
    write_bytes(dir / "word.pcd",
                "VERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\n"
                "WIDTH 1\nDATA ascii\n1 2 3 bright\n");
    expect_io_error([&] { shine::read_pcd_scan(dir / "word.pcd"); }, dir / "word.pcd",
                    "line 7: intensity 'bright' is not a number");
}

TEST(Pcd, BinaryWithPaddingAndMixedSizes) {
    const fs::path path = test_dir("binary") / "scan.pcd";
    std::string file =
        "VERSION .7\nFIELDS rgb x _ y z\nSIZE 1 8 1 4 4\nTYPE U F U F F\nCOUNT 3 1 2 1 1\n"
        "WIDTH 2\nHEIGHT 1\nDATA binary\n";
    const float yz[2][2] = {{2.5f, -3.0f}, {1e-3f, 4e4f}};
    const double x[2] = {1.0 / 3.0, -17.0};
    for (int i = 0; i < 2; ++i) {
        file += std::string("\x01\x02\x03", 3);
        put<double>(file, x[i]);
        file += std::string("\xff\xff", 2);
        put<float>(file, yz[i][0]);
        put<float>(file, yz[i][1]);
    }
    write_bytes(path, file);
    const auto points = shine::read_pcd_points(path);
    ASSERT_EQ(points.size(), 2u);
    EXPECT_EQ(points[0], Eigen::Vector3f(static_cast<float>(1.0 / 3.0), 2.5f, -3.0f));
    EXPECT_EQ(points[1], Eigen::Vector3f(-17.0f, 1e-3f, 4e4f));
}

TEST(Pcd, BinaryCompressedLiteralOnly) {
    const fs::path path = test_dir("compressed_literal") / "scan.pcd";
    const auto points = random_points(100, 2);
    write_bytes(path, compressed_pcd(points, /*literal_only=*/true));
    const auto back = shine::read_pcd_points(path);
    ASSERT_EQ(back.size(), points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
        // x went through a double: exact, since it was a float to begin with.
        EXPECT_EQ(back[i], points[i]) << i;
    }
}

TEST(Pcd, BinaryCompressedWithBackReferences) {
    const fs::path path = test_dir("compressed_backref") / "scan.pcd";
    // A regular grid repeats byte patterns, so the compressor uses back-references of all sizes.
    std::vector<Eigen::Vector3f> points;
    for (int i = 0; i < 300; ++i) points.emplace_back(static_cast<float>(i % 10), 2.0f, 0.5f);
    const std::string file = compressed_pcd(points, /*literal_only=*/false);
    write_bytes(path, file);
    // Make sure the stream really contains back-references: it is much smaller than the data.
    EXPECT_LT(fs::file_size(path), 300u * 20 / 4);
    EXPECT_EQ(shine::read_pcd_points(path), points);
    // The intensity column (the first in the block) for every point.
    EXPECT_EQ(shine::read_pcd_scan(path).intensity, std::vector<float>(300, 7.0f));
}

TEST(PcdErrors, HeaderProblemsNameFileAndLine) {
    const fs::path dir = test_dir("errors_header");
    expect_io_error([&] { shine::read_pcd_points(dir / "missing.pcd"); }, dir / "missing.pcd",
                    "does not exist");
    write_bytes(dir / "empty.pcd", "");
    expect_io_error([&] { shine::read_pcd_points(dir / "empty.pcd"); }, dir / "empty.pcd", "empty");
    write_bytes(dir / "garbage.pcd", "hello world\n\x01\x02");
    expect_io_error([&] { shine::read_pcd_points(dir / "garbage.pcd"); }, dir / "garbage.pcd",
                    "line 1");
    write_bytes(dir / "nodata.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "nodata.pcd"); }, dir / "nodata.pcd",
                    "DATA");
    write_bytes(dir / "noz.pcd",
                "FIELDS x y w\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "noz.pcd"); }, dir / "noz.pcd",
                    "no field 'z'");
    write_bytes(dir / "mismatch.pcd",
                "FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "mismatch.pcd"); }, dir / "mismatch.pcd",
                    "3 FIELDS but 2 SIZE");
    write_bytes(dir / "int_x.pcd",
                "FIELDS x y z\nSIZE 4 4 4\nTYPE I F F\nWIDTH 1\nDATA ascii\n1 2 3\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "int_x.pcd"); }, dir / "int_x.pcd",
                    "field 'x' must be TYPE F");
    write_bytes(dir / "points.pcd",
                "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nPOINTS 3\nDATA ascii\n1 2 3\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "points.pcd"); }, dir / "points.pcd",
                    "differs from WIDTH");
    write_bytes(dir / "width.pcd",
                "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH -1\nDATA ascii\n1 2 3\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "width.pcd"); }, dir / "width.pcd",
                    "line 4");
}

TEST(PcdErrors, AsciiBodyProblemsNameTheLine) {
    const fs::path dir = test_dir("errors_ascii");
    const std::string header = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 3\nDATA ascii\n";
    write_bytes(dir / "word.pcd", header + "1 2 3\n4 five 6\n7 8 9\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "word.pcd"); }, dir / "word.pcd",
                    "line 7: 'five' is not a number");
    write_bytes(dir / "count.pcd", header + "1.00 2.00 3.00\n4.00 5.00\n7.00 8.00 9.00\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "count.pcd"); }, dir / "count.pcd",
                    "line 7: expected 3 values, found 2");
    write_bytes(dir / "short.pcd", header + "1.00 2.00 3.00\n4.00 5.00 6.00\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "short.pcd"); }, dir / "short.pcd",
                    "2 of 3 points");
    write_bytes(dir / "long.pcd", header + "1 2 3\n4 5 6\n7 8 9\n1 1 1\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "long.pcd"); }, dir / "long.pcd",
                    "line 9: more data lines");
    write_bytes(dir / "huge.pcd",
                "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 900000000000\nDATA ascii\n1 2 3\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "huge.pcd"); }, dir / "huge.pcd",
                    "900000000000 points");
}

TEST(PcdErrors, BinaryTruncationAndHugeCounts) {
    const fs::path dir = test_dir("errors_binary");
    shine::write_pcd_points(dir / "full.pcd", random_points(10, 3));
    std::ifstream in(dir / "full.pcd", std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    write_bytes(dir / "cut.pcd", bytes.substr(0, bytes.size() - 1));
    expect_io_error([&] { shine::read_pcd_points(dir / "cut.pcd"); }, dir / "cut.pcd", "truncated");
    write_bytes(dir / "huge.pcd",
                "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 4000000000\nHEIGHT 4000000000\n"
                "DATA binary\n0123456789ab");
    expect_io_error([&] { shine::read_pcd_points(dir / "huge.pcd"); }, dir / "huge.pcd",
                    "byte offset");
    write_bytes(dir / "overflow.pcd",
                "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 18446744073709551615\nHEIGHT 2\n"
                "DATA binary\n0123456789ab");
    expect_io_error([&] { shine::read_pcd_points(dir / "overflow.pcd"); }, dir / "overflow.pcd",
                    "overflows");
}

TEST(PcdErrors, CorruptCompressedBlocks) {
    const fs::path dir = test_dir("errors_compressed");
    const auto points = random_points(20, 4);
    const std::string good = compressed_pcd(points, /*literal_only=*/true);
    const std::size_t sizes_at = good.find("binary_compressed\n") + 18;

    // Truncated block: the declared compressed size exceeds what follows.
    write_bytes(dir / "cut.pcd", good.substr(0, good.size() - 5));
    expect_io_error([&] { shine::read_pcd_points(dir / "cut.pcd"); }, dir / "cut.pcd", "truncated");
    // Missing size words entirely.
    write_bytes(dir / "nosizes.pcd", good.substr(0, sizes_at + 3));
    expect_io_error([&] { shine::read_pcd_points(dir / "nosizes.pcd"); }, dir / "nosizes.pcd",
                    "sizes are missing");

    // Uncompressed size that does not match the header's points.
    std::string wrong_size = good;
    const std::uint32_t bogus = 12345;
    std::memcpy(&wrong_size[sizes_at + 4], &bogus, 4);
    write_bytes(dir / "wrong_size.pcd", wrong_size);
    expect_io_error([&] { shine::read_pcd_points(dir / "wrong_size.pcd"); }, dir / "wrong_size.pcd",
                    "does not match");

    // A header asking for far more points than the block could ever expand to.
    std::string file =
        "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 300000000\nDATA binary_compressed\n";
    put<std::uint32_t>(file, 4);
    put<std::uint32_t>(file, 3600000000u);
    file += std::string("\x00\x01\x02\x03", 4);
    write_bytes(dir / "bomb.pcd", file);
    expect_io_error([&] { shine::read_pcd_points(dir / "bomb.pcd"); }, dir / "bomb.pcd",
                    "impossible");

    // A back-reference that points before the start of the output.
    std::string backref = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA binary_compressed\n";
    const std::string block = std::string("\x00\x41", 2) + std::string("\xe0\x01\x10", 3);
    put<std::uint32_t>(backref, static_cast<std::uint32_t>(block.size()));
    put<std::uint32_t>(backref, 12);
    write_bytes(dir / "backref.pcd", backref + block);
    expect_io_error([&] { shine::read_pcd_points(dir / "backref.pcd"); }, dir / "backref.pcd",
                    "corrupt LZF block");

    // A literal run promising more bytes than the block holds.
    std::string run = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA binary_compressed\n";
    const std::string run_block = std::string("\x1f\x00\x00\x00", 4);
    put<std::uint32_t>(run, static_cast<std::uint32_t>(run_block.size()));
    put<std::uint32_t>(run, 12);
    write_bytes(dir / "run.pcd", run + run_block);
    expect_io_error([&] { shine::read_pcd_points(dir / "run.pcd"); }, dir / "run.pcd",
                    "literal run past the end");

    // A valid stream that produces fewer bytes than declared.
    std::string few = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nDATA binary_compressed\n";
    const std::string few_block = lzf_literals(std::string(8, '\0'));
    put<std::uint32_t>(few, static_cast<std::uint32_t>(few_block.size()));
    put<std::uint32_t>(few, 12);
    write_bytes(dir / "few.pcd", few + few_block);
    expect_io_error([&] { shine::read_pcd_points(dir / "few.pcd"); }, dir / "few.pcd",
                    "decompressed 8 bytes");
}

TEST(PcdErrors, EveryTruncationAndByteFlipGivesIoErrorOrPoints) {
    const fs::path dir = test_dir("fuzz");
    std::vector<std::string> files;
    std::vector<Eigen::Vector3f> grid;
    for (int i = 0; i < 40; ++i) grid.emplace_back(static_cast<float>(i % 4), 1.0f, 2.0f);
    files.push_back(compressed_pcd(grid, /*literal_only=*/false));
    shine::write_pcd_points(dir / "bin.pcd", random_points(5, 8));
    std::ifstream in(dir / "bin.pcd", std::ios::binary);
    files.emplace_back((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    files.push_back("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nDATA ascii\n1 2 3\n4 5 6\n");
    std::mt19937 rng(10);
    for (const std::string& original : files) {
        std::vector<std::string> variants;
        for (std::size_t n = 0; n < original.size(); ++n) variants.push_back(original.substr(0, n));
        for (int k = 0; k < 300; ++k) {
            std::string v = original;
            v[rng() % v.size()] = static_cast<char>(rng() % 256);
            variants.push_back(v);
        }
        int failures = 0;
        for (const std::string& v : variants) {
            write_bytes(dir / "variant.pcd", v);
            try {
                shine::read_pcd_points(dir / "variant.pcd");
            } catch (const shine::IoError& e) {
                ++failures;
                ASSERT_NE(std::string(e.what()).find("variant.pcd"), std::string::npos);
            }
        }
        // Prefixes that cut the data are errors; only a cut trailing newline may still parse.
        EXPECT_GE(failures, static_cast<int>(original.size()) - 1);
    }
}

TEST(PcdErrors, HeaderValuesNameTheirOwnLine) {
    const fs::path dir = test_dir("errors_lines");
    write_bytes(dir / "size.pcd",
                "# c\nFIELDS x y z\nSIZE 4 3 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "size.pcd"); }, dir / "size.pcd",
                    "line 3: SIZE of field 'y' is '3'");
    write_bytes(dir / "type.pcd",
                "FIELDS x y z\nSIZE 4 4 4\nTYPE F F Q\nWIDTH 1\nDATA ascii\n1 2 3\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "type.pcd"); }, dir / "type.pcd",
                    "line 3: TYPE of field 'z' is 'Q'");
    write_bytes(dir / "count.pcd",
                "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 0\nWIDTH 1\nDATA ascii\n1 2 3\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "count.pcd"); }, dir / "count.pcd",
                    "line 4: COUNT of field 'z' is '0'");
    write_bytes(dir / "points.pcd",
                "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 1\nPOINTS 3\nDATA ascii\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "points.pcd"); }, dir / "points.pcd",
                    "line 6: POINTS 3 differs from WIDTH * HEIGHT = 2");
    write_bytes(dir / "no_data.pcd", "FIELDS x y z\nSIZE 4 4 4\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "no_data.pcd"); }, dir / "no_data.pcd",
                    "header (lines 1-2): ends without a DATA line");
    write_bytes(dir / "garbage.pcd", "\xff\xfe\x01junk\n");
    expect_io_error([&] { shine::read_pcd_points(dir / "garbage.pcd"); }, dir / "garbage.pcd",
                    "line 1: unknown header keyword '\\xff\\xfe\\x01junk'");
}

TEST(PcdErrors, HugeCountsFailFastWithoutAllocating) {
    const fs::path dir = test_dir("errors_tera");
    const auto start = std::chrono::steady_clock::now();
    for (const char* encoding : {"ascii", "binary", "binary_compressed"}) {
        SCOPED_TRACE(encoding);
        const std::string name = std::string("tera_") + encoding + ".pcd";
        const std::string header =
            "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1000000000000\nDATA " +
            std::string(encoding) + "\n";
        write_bytes(dir / name, header + "0123456789ab0123456789ab");
        // Ascii names the first data line, binary the first data byte.
        expect_io_error([&] { shine::read_pcd_points(dir / name); }, dir / name,
                        std::string(encoding) == "ascii"
                            ? "line 6: header declares 1000000000000 points"
                            : "byte offset " + std::to_string(header.size()));
    }
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0);
}

TEST(Pcd, ParsesBytesInMemory) {
    const auto points = shine::parse_pcd_points(
        "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nDATA ascii\n1 2 3\n4 5 6", "memory.pcd");
    ASSERT_EQ(points.size(), 2u);
    EXPECT_EQ(points[1], Eigen::Vector3f(4, 5, 6));
}
