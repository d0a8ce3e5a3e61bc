#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>

#include "shine/core/error.hpp"
#include "shine/io/vdb_file_check.hpp"

namespace fs = std::filesystem;

namespace {

fs::path test_dir(const std::string& name) {
    const fs::path dir = fs::path(SHINE_TEST_TMP_DIR) / "io_vdb_check" / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

/// The seeds of fuzz_vdb: a tiny map.vdb and surface.vdb written by OpenVDB itself.
const fs::path kSeedDir =
    fs::path(__FILE__).parent_path().parent_path() / "fuzz" / "corpus" / "fuzz_vdb";

std::string read_bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

template <typename T>
void put(std::string& out, T value) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    out.append(bytes, sizeof(T));
}

void put_string(std::string& out, const std::string& s) {
    put<std::uint32_t>(out, static_cast<std::uint32_t>(s.size()));
    out += s;
}

void put_meta(std::string& out, const std::string& name, const std::string& type,
              const std::string& value) {
    put_string(out, name);
    put_string(out, type);
    put_string(out, value);  // a byte count and the value bytes
}

/// How to make a hand-made file, and where its fields ended up (for targeted corruption).
struct Layout {
    // Input.
    std::string grid_name = "surface";
    std::string grid_type = "Tree_float_5_4_3";
    bool one_leaf = false;            ///< a tree with one leaf of 4 active voxels (else empty)
    std::uint32_t compression = 0x2;  ///< COMPRESS_ACTIVE_MASK, | 0x1 zip, | 0x4 blosc
    std::string delayed_load;         ///< value of a "__delayedload" grid metadata entry, if any
    // Output: byte offsets.
    std::size_t version = 8;
    std::size_t offset_flag = 20;
    std::size_t file_meta_count = 57;
    std::size_t int32_meta_size = 0;  ///< byte count of the "levels" int32 entry
    std::size_t grid_count = 0;
    std::size_t grid_name_at = 0;
    std::size_t offsets = 0;
    std::size_t flags = 0;
    std::size_t transform = 0;
    std::size_t buffer_count = 0;
    std::size_t root_children = 0;
    std::size_t child_origin = 0;
    std::size_t leaf_buffer_mask = 0;
    std::size_t leaf_values = 0;  ///< the leaf's value flag byte; its data follow
};

/// Appends a value block of readCompressedValues: flag 0 (no inactive values stored), then
/// `bytes` of values, raw or as an uncompressed chunk with a negative size prefix.
void put_values(std::string& out, const std::string& bytes, std::uint32_t compression) {
    put<std::int8_t>(out, 0);
    if (compression & 0x5) put<std::int64_t>(out, -static_cast<std::int64_t>(bytes.size()));
    out += bytes;
}

/// A minimal OpenVDB file as vdb_file_check.hpp describes it: two file metadata entries and one
/// float grid with a uniform-scale transform and an empty tree or a tree of one leaf.
std::string minimal_vdb(Layout& l) {
    std::string b;
    put<std::int64_t>(b, 0x56444220);
    put<std::uint32_t>(b, 224);  // format version
    put<std::uint32_t>(b, 10);   // library version 10.0
    put<std::uint32_t>(b, 0);
    put<std::uint8_t>(b, 1);  // has grid offsets
    b += "0123456789abcdef0123456789abcdef0123";
    put<std::int32_t>(b, 2);
    put_meta(b, "creator", "string", "test");
    put_string(b, "levels");
    put_string(b, "int32");
    l.int32_meta_size = b.size();
    put<std::uint32_t>(b, 4);
    put<std::int32_t>(b, 3);
    l.grid_count = b.size();
    put<std::int32_t>(b, 1);
    l.grid_name_at = b.size();
    put_string(b, l.grid_name);
    put_string(b, l.grid_type);
    put_string(b, "");  // not an instance
    l.offsets = b.size();
    const std::size_t grid_pos = b.size() + 24;
    // Grid header: compression, metadata, transform, topology.
    std::string g;
    put<std::uint32_t>(g, l.compression);
    put<std::int32_t>(g, l.delayed_load.empty() ? 1 : 2);
    put_meta(g, "class", "string", "level set");
    if (!l.delayed_load.empty()) put_meta(g, "file_delayed_load", "__delayedload", l.delayed_load);
    l.transform = grid_pos + g.size();
    put_string(g, "UniformScaleMap");
    g += std::string(120, '\0');
    l.buffer_count = grid_pos + g.size();
    put<std::int32_t>(g, 1);
    put<float>(g, 0.3f);  // background
    put<std::uint32_t>(g, 0);
    l.root_children = grid_pos + g.size();
    put<std::uint32_t>(g, l.one_leaf ? 1 : 0);
    const std::string leaf_mask = std::string(1, '\x0f') + std::string(63, '\0');
    if (l.one_leaf) {
        l.child_origin = grid_pos + g.size();
        for (int k = 0; k < 3; ++k) put<std::int32_t>(g, 0);
        // 32^3 node: child 0 set, no active tiles, no tile values (active-mask compression).
        g += std::string(1, '\x01') + std::string(4095, '\0') + std::string(4096, '\0');
        put_values(g, "", l.compression);
        // 16^3 node: child 0 set.
        g += std::string(1, '\x01') + std::string(511, '\0') + std::string(512, '\0');
        put_values(g, "", l.compression);
        g += leaf_mask;
    }
    const std::size_t block_pos = grid_pos + g.size();
    std::string voxels;
    if (l.one_leaf) {
        l.leaf_buffer_mask = block_pos;
        voxels += leaf_mask;
        l.leaf_values = block_pos + voxels.size();
        std::string values;
        for (float v : {-0.1f, 0.0f, 0.1f, 0.2f}) put<float>(values, v);
        put_values(voxels, values, l.compression);
    }
    put<std::int64_t>(b, static_cast<std::int64_t>(grid_pos));
    put<std::int64_t>(b, static_cast<std::int64_t>(block_pos));
    put<std::int64_t>(b, static_cast<std::int64_t>(block_pos + voxels.size()));
    l.flags = b.size();
    return b + g + voxels;
}

std::string minimal_vdb() {
    Layout l;
    return minimal_vdb(l);
}

template <typename F>
void expect_io_error(F&& f, const std::string& fragment) {
    try {
        f();
        ADD_FAILURE() << "expected IoError containing '" << fragment << "'";
    } catch (const shine::IoError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("'bytes.vdb', byte offset"), std::string::npos) << msg;
        EXPECT_NE(msg.find(fragment), std::string::npos)
            << "missing '" << fragment << "' in: " << msg;
    }
}

void expect_corruption_caught(std::string bytes, const std::string& fragment) {
    expect_io_error([&] { shine::check_vdb_bytes(bytes, "bytes.vdb"); }, fragment);
}

template <typename T>
std::string patched(std::string bytes, std::size_t at, T value) {
    std::memcpy(&bytes[at], &value, sizeof(T));
    return bytes;
}

}  // namespace

TEST(VdbFileCheck, ReadsTheStructureOfAMinimalFile) {
    const shine::VdbFileInfo info = shine::check_vdb_bytes(minimal_vdb(), "bytes.vdb");
    EXPECT_EQ(info.format_version, 224u);
    EXPECT_EQ(info.file_metadata, (std::vector<std::string>{"creator", "levels"}));
    ASSERT_EQ(info.grids.size(), 1u);
    EXPECT_EQ(info.grids[0].name, "surface");
    EXPECT_EQ(info.grids[0].type, "Tree_float_5_4_3");
    EXPECT_EQ(info.grids[0].grid_class, "level set");
    EXPECT_FALSE(info.grids[0].half_float);
}

TEST(VdbFileCheck, StripsUniqueNameAndHalfFloatSuffixes) {
    Layout l;
    l.grid_name = std::string("surface\x1e") + "1";
    l.grid_type = "Tree_float_5_4_3_HalfFloat";
    const shine::VdbFileInfo info = shine::check_vdb_bytes(minimal_vdb(l), "bytes.vdb");
    ASSERT_EQ(info.grids.size(), 1u);
    EXPECT_EQ(info.grids[0].name, "surface");
    EXPECT_EQ(info.grids[0].type, "Tree_float_5_4_3");
    EXPECT_TRUE(info.grids[0].half_float);
}

TEST(VdbFileCheck, EveryTruncationIsReportedWithItsByteOffset) {
    for (std::uint32_t compression : {0x2u, 0x3u}) {
        Layout l;
        l.one_leaf = true;
        l.compression = compression;
        const std::string full = minimal_vdb(l);
        ASSERT_NO_THROW(shine::check_vdb_bytes(full, "bytes.vdb"));
        for (std::size_t n = 0; n < full.size(); n += (n < 200 ? 1 : 13)) {
            SCOPED_TRACE(n);
            expect_corruption_caught(full.substr(0, n), "");
        }
    }
}

TEST(VdbFileCheck, CorruptHeaderFields) {
    Layout l;
    const std::string good = minimal_vdb(l);
    expect_corruption_caught("#!/bin/sh\necho not a vdb\n", "byte offset 0: not an OpenVDB file");
    expect_corruption_caught(patched<std::uint32_t>(good, l.version, 221),
                             "byte offset 8: format version 221 is older than 222");
    expect_corruption_caught(patched<std::uint32_t>(good, l.version, 300),
                             "format version 300 is newer than 224");
    expect_corruption_caught(patched<std::uint8_t>(good, l.offset_flag, 0),
                             "byte offset 20: written as a stream");
    expect_corruption_caught(patched<std::int32_t>(good, l.file_meta_count, -1),
                             "byte offset 57: file metadata count -1 is impossible");
    expect_corruption_caught(patched<std::int32_t>(good, l.file_meta_count, 1 << 30),
                             "file metadata count 1073741824 is impossible");
    // OpenVDB reads an int32 value whatever size the file gives, then reads out of step.
    expect_corruption_caught(patched<std::uint32_t>(good, l.int32_meta_size, 8),
                             "byte offset " + std::to_string(l.int32_meta_size) +
                                 ": file metadata 'levels' of type int32 has 8 bytes, expected 4");
    // A 4 GB string length must be caught before anything is allocated.
    expect_corruption_caught(patched<std::uint32_t>(good, l.file_meta_count + 4, 0xffffffffu),
                             "file metadata name needs 4294967295 bytes");
    expect_corruption_caught(patched<std::int32_t>(good, l.grid_count, -3), "grid count -3");
    expect_corruption_caught(patched<std::int32_t>(good, l.grid_count, 2000000000),
                             "grid count 2000000000 is impossible");
}

TEST(VdbFileCheck, CorruptGridDescriptors) {
    Layout l;
    const std::string good = minimal_vdb(l);
    const auto offset = [&](int k) { return l.offsets + 8 * static_cast<std::size_t>(k); };
    // Grid position before the end of its own descriptor.
    expect_corruption_caught(patched<std::int64_t>(good, offset(0), 10),
                             "grid 0 'surface' has inconsistent offsets (grid 10");
    // Voxel data before the grid header.
    expect_corruption_caught(patched<std::int64_t>(good, offset(1), 0), "inconsistent offsets");
    // End past the end of the file.
    expect_corruption_caught(
        patched<std::int64_t>(good, offset(2), 1 << 30),
        "the file is truncated: grid 0 'surface' ends at byte 1073741824 but the file has " +
            std::to_string(good.size()) + " bytes");
    expect_corruption_caught(patched<std::int64_t>(good, offset(2), -1), "inconsistent offsets");
    expect_corruption_caught(patched<std::uint32_t>(good, l.flags, 0x100),
                             "byte offset " + std::to_string(l.flags) +
                                 ": grid 0 'surface' has unknown compression flags 256");
    // Grid metadata that runs into the voxel data: a block position just after the flags.
    expect_corruption_caught(
        patched<std::int64_t>(good, offset(1), static_cast<std::int64_t>(l.flags + 6)),
        "metadata count needs 4 bytes but only 2 remain in the grid header");
    // Grid names are quoted printably.
    std::string binary_name = good;
    binary_name[l.grid_name_at + 4] = '\x01';
    expect_corruption_caught(patched<std::int64_t>(binary_name, offset(2), -1),
                             "grid 0 '\\x01urface'");
}

TEST(VdbFileCheck, CorruptTransformTopologyAndVoxelData) {
    Layout l;
    l.one_leaf = true;
    l.compression = 0x3;  // zip | active mask: values carry an int64 size prefix
    const std::string good = minimal_vdb(l);
    const std::size_t size_prefix = l.leaf_values + 1;
    // OpenVDB 10 reads -size bytes into a buffer sized for the expected values before comparing
    // the two: a heap overflow that fuzzing found. The check compares first.
    expect_corruption_caught(patched<std::int64_t>(good, size_prefix, -17),
                             "byte offset " + std::to_string(size_prefix) +
                                 ": grid 0 'surface' leaf 0 values: 17 uncompressed bytes where "
                                 "16 are expected");
    expect_corruption_caught(patched<std::int64_t>(good, size_prefix, INT64_MIN), "uncompressed");
    // A compressed size beyond the data.
    expect_corruption_caught(patched<std::int64_t>(good, size_prefix, 1LL << 40),
                             "values needs 1099511627776 bytes");
    expect_corruption_caught(patched<std::int8_t>(good, l.leaf_values, 9),
                             "unknown value-compression flag 9");
    expect_corruption_caught(patched<std::uint8_t>(good, l.leaf_buffer_mask, 0x1f),
                             "the value mask of leaf 0 differs from the one in the topology");
    expect_corruption_caught(patched<std::uint32_t>(good, l.root_children, 1000000),
                             "1000000 root children cannot fit");
    expect_corruption_caught(patched<std::int32_t>(good, l.child_origin, 8),
                             "root child origin (8, 0, 0) is not a multiple of 4096");
    expect_corruption_caught(patched<std::int32_t>(good, l.buffer_count, 2), "2 buffers per node");
    std::string curved = good;
    std::memcpy(&curved[l.transform + 4], "Curved", 6);
    expect_corruption_caught(curved, "unknown transform type 'CurvedmScaleMap'");
    // Four more active voxels in both copies of the leaf's mask: the data hold too few values.
    const std::size_t topology_mask = l.leaf_buffer_mask - 64;
    expect_corruption_caught(
        patched<std::uint8_t>(patched<std::uint8_t>(good, l.leaf_buffer_mask, 0xff), topology_mask,
                              0xff),
        "16 uncompressed bytes where 32 are expected");
}

TEST(VdbFileCheck, BloscHeadersMustMatchTheExpectedSizes) {
    // Blosc trusts its header: the uncompressed size must be the values OpenVDB expects and the
    // compressed size the bytes the file holds.
    Layout l;
    l.one_leaf = true;
    l.compression = 0x6;  // blosc | active mask
    std::string good = minimal_vdb(l);
    // Replace the leaf's uncompressed chunk (-16, 16 bytes) by a 20-byte blosc block.
    const std::size_t size_prefix = l.leaf_values + 1;
    std::string block(4, '\0');
    block[0] = 2;                   // format version
    block[3] = 4;                   // type size
    put<std::uint32_t>(block, 16);  // nbytes
    put<std::uint32_t>(block, 16);  // block size
    put<std::uint32_t>(block, 20);  // cbytes
    block += "abcd";
    const auto with_block = [&](const std::string& b) {
        std::string file = good.substr(0, size_prefix);
        put<std::int64_t>(file, static_cast<std::int64_t>(b.size()));
        file += b;
        // The grid's end offset moves with the data.
        const std::int64_t end = static_cast<std::int64_t>(file.size());
        std::memcpy(&file[l.offsets + 16], &end, 8);
        return file;
    };
    EXPECT_NO_THROW(shine::check_vdb_bytes(with_block(block), "bytes.vdb"));
    std::string wrong_nbytes = block;
    const std::uint32_t huge = 1u << 31;
    std::memcpy(&wrong_nbytes[4], &huge, 4);
    expect_corruption_caught(with_block(wrong_nbytes), "blosc header (2147483648 bytes");
    std::string wrong_cbytes = block;
    const std::uint32_t more = 4000;
    std::memcpy(&wrong_cbytes[12], &more, 4);
    expect_corruption_caught(with_block(wrong_cbytes), "4000 compressed");
    expect_corruption_caught(with_block("tiny"), "shorter than its 16-byte header");
}

TEST(VdbFileCheck, DelayedLoadMetadataMustFitItsEntryAndTheTree) {
    // count, mask block size 0, one mask byte per leaf, 0xffffffff: no compressed sizes.
    std::string value;
    put<std::uint32_t>(value, 1);
    put<std::uint32_t>(value, 0);
    value += '\0';
    put<std::uint32_t>(value, 0xffffffffu);
    Layout l;
    l.one_leaf = true;
    l.delayed_load = value;
    EXPECT_NO_THROW(shine::check_vdb_bytes(minimal_vdb(l), "bytes.vdb"));
    // More leaves than the tree has: OpenVDB would size its tables from this count.
    std::string two;
    put<std::uint32_t>(two, 2);
    put<std::uint32_t>(two, 0);
    two += std::string(2, '\0');
    put<std::uint32_t>(two, 0xffffffffu);
    l.delayed_load = two;
    expect_corruption_caught(minimal_vdb(l),
                             "delayed-load metadata lists 2 leaves but the tree has 1");
    // A count whose masks do not fit in the entry.
    std::string many = value;
    const std::uint32_t count = 1u << 30;
    std::memcpy(&many[0], &count, 4);
    l.delayed_load = many;
    expect_corruption_caught(minimal_vdb(l), "'file_delayed_load' needs 1073741824 bytes");
}

TEST(VdbFileCheck, FilesWrittenByOpenVdbPass) {
    ASSERT_TRUE(fs::exists(kSeedDir / "map.vdb")) << kSeedDir;
    const shine::VdbFileInfo map = shine::check_vdb_file(kSeedDir / "map.vdb");
    EXPECT_NE(std::find(map.file_metadata.begin(), map.file_metadata.end(), "shine_format"),
              map.file_metadata.end());
    ASSERT_EQ(map.grids.size(), 2u);
    EXPECT_EQ(map.grids[0].name, "feature_level_0");
    EXPECT_EQ(map.grids[1].type, "Tree_int32_5_4_3");

    const shine::VdbFileInfo surface = shine::check_vdb_file(kSeedDir / "surface.vdb");
    ASSERT_EQ(surface.grids.size(), 1u);
    EXPECT_EQ(surface.grids[0].name, "surface");
    EXPECT_EQ(surface.grids[0].type, "Tree_float_5_4_3");
    EXPECT_EQ(surface.grids[0].grid_class, "level set");
}

TEST(VdbFileCheck, FuzzRegressionsAreRejected) {
    // Files fuzz_vdb found: without the check, OpenVDB 10 overflows a heap buffer
    // (regression_overflow.vdb), tries to allocate 64 GB (regression_64gb_chunk.vdb) or grows
    // to 5 GB over 20 s on a 641-byte file (regression_truncated_5gb.vdb).
    int regressions = 0;
    for (const auto& entry : fs::directory_iterator(kSeedDir)) {
        const std::string name = entry.path().filename().string();
        if (name == "map.vdb" || name == "surface.vdb") continue;
        // Well-formed files whose contents the loader must reject (load_regression_*.vdb: a
        // leaf size OpenVDB cannot scale; MapFileFormat.ALeafSizeOpenVdbCannotScale...).
        if (name.rfind("load_", 0) == 0) continue;
        SCOPED_TRACE(name);
        try {
            shine::check_vdb_file(entry.path());
            ADD_FAILURE() << "accepted";
        } catch (const shine::IoError& e) {
            EXPECT_NE(std::string(e.what()).find(name + "', byte offset "), std::string::npos)
                << e.what();
        }
        regressions += name.rfind("regression_", 0) == 0;
    }
    EXPECT_GE(regressions, 3);
}

TEST(VdbFileCheck, TruncatedAndFlippedRealFilesNeverCrash) {
    std::mt19937 rng(5);
    for (const char* name : {"map.vdb", "surface.vdb"}) {
        SCOPED_TRACE(name);
        const std::string full = read_bytes(kSeedDir / name);
        ASSERT_GT(full.size(), 100u);
        int reported = 0;
        for (std::size_t n = 0; n < full.size(); n += 7) {
            try {
                shine::check_vdb_bytes(full.substr(0, n), "bytes.vdb");
            } catch (const shine::IoError&) {
                ++reported;
            }
        }
        // Every cut removes the end of the last grid.
        EXPECT_EQ(reported, static_cast<int>((full.size() + 6) / 7));
        for (int k = 0; k < 500; ++k) {
            std::string v = full;
            v[rng() % v.size()] = static_cast<char>(rng() % 256);
            try {
                shine::check_vdb_bytes(v, "bytes.vdb");
            } catch (const shine::IoError& e) {
                ASSERT_NE(std::string(e.what()).find("bytes.vdb"), std::string::npos);
            }
        }
    }
}

TEST(VdbFileCheck, MissingFileAndDirectory) {
    const fs::path dir = test_dir("paths");
    try {
        shine::check_vdb_file(dir / "missing.vdb", "map file");
        FAIL() << "expected IoError";
    } catch (const shine::IoError& e) {
        EXPECT_NE(std::string(e.what()).find("map file '"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("does not exist"), std::string::npos) << e.what();
    }
    EXPECT_THROW(shine::check_vdb_file(dir), shine::IoError);
    std::ofstream(dir / "empty.vdb").close();
    EXPECT_THROW(shine::check_vdb_file(dir / "empty.vdb"), shine::IoError);
}
