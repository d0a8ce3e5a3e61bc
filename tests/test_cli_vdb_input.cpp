// Damaged .vdb files given to `shine mesh` and `shine bake`: every one must stop with a message
// naming the file and the byte offset of the problem (from check_vdb_file, before OpenVDB reads
// anything), a non-zero exit, and no output file.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "cli_test_support.hpp"

namespace fs = std::filesystem;
using namespace shine::cli_test;

namespace {

fs::path test_dir() { return test_dir_of("cli_vdb_input"); }

CliResult run(const std::string& args) { return run_shine(args, test_dir()); }

std::string read_bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& path, const std::string& bytes) {
    std::ofstream(path, std::ios::binary)
        .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

/// A small real map.vdb and surface.vdb written by `shine map` (made once per test process).
const fs::path& mapped() {
    static const fs::path out = [] {
        const fs::path street = test_dir() / "street";
        const fs::path o = test_dir() / "out";
        fs::remove_all(street);
        fs::remove_all(o);
        CliResult r = run("simulate -o " + street.string() + " --frames 2 --seed 3 --no-progress");
        EXPECT_EQ(r.exit_code, 0) << r.output;
        r = run("map " + street.string() + " -o " + o.string() +
                " --iterations 50 --threads 2 --no-eval -q");
        EXPECT_EQ(r.exit_code, 0) << r.output;
        return o;
    }();
    return out;
}

// Offset of the value byte count of the string metadata entry `name` (file or grid metadata):
// an entry is its name, its type name (each a uint32 length + bytes) and a uint32 byte count.
std::size_t string_metadata_size_offset(const std::string& vdb, const std::string& name) {
    std::string entry;
    for (const std::string& s : {name, std::string("string")}) {
        const auto length = static_cast<std::uint32_t>(s.size());
        entry.append(reinterpret_cast<const char*>(&length), 4);
        entry += s;
    }
    const std::size_t at = vdb.find(entry);
    EXPECT_NE(at, std::string::npos) << "no string metadata '" << name << "'";
    return at == std::string::npos ? 0 : at + entry.size();
}

/// Damaged versions of `valid`, each with a name for messages; `metadata_name` is a string
/// metadata entry of the file whose byte count is corrupted.
std::vector<std::pair<std::string, std::string>> damaged_versions(
    const std::string& valid, const std::string& metadata_name) {
    std::vector<std::pair<std::string, std::string>> out;
    out.emplace_back("empty", "");
    out.emplace_back("garbage", std::string("this is not an OpenVDB file, just text\n"));
    for (const std::size_t size : {std::size_t{7}, std::size_t{40}, std::size_t{100},
                                   valid.size() / 3, valid.size() / 2, valid.size() - 1}) {
        out.emplace_back("truncated_" + std::to_string(size), valid.substr(0, size));
    }
    // After the 57-byte header (magic, versions, has-offsets flag, uuid) and the file metadata
    // count: the first file metadata name's length (map.vdb) or the grid count (surface.vdb,
    // which has no file metadata).
    std::string flipped_count = valid;
    const std::uint32_t huge = 0x7ffffff0u;
    std::memcpy(&flipped_count[61], &huge, 4);
    out.emplace_back("flipped_length_at_61", flipped_count);
    std::string flipped_size = valid;
    const std::size_t at = string_metadata_size_offset(valid, metadata_name);
    flipped_size[at + 3] = static_cast<char>(flipped_size[at + 3] ^ 0x40);  // +1 GiB
    out.emplace_back("flipped_metadata_size", flipped_size);
    return out;
}

void expect_clear_failure(const CliResult& r, const std::string& file_name) {
    EXPECT_NE(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find(file_name), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("internal error"), std::string::npos) << r.output;
}

}  // namespace

TEST(DamagedVdb, MeshAndBakeRejectDamagedMaps) {
    const std::string valid = read_bytes(mapped() / "map.vdb");
    ASSERT_GT(valid.size(), 1000u);
    for (const auto& [name, bytes] : damaged_versions(valid, "shine_format")) {
        SCOPED_TRACE(name);
        const fs::path damaged = test_dir() / ("map_" + name + ".vdb");
        write_bytes(damaged, bytes);
        const fs::path mesh = test_dir() / ("mesh_" + name + ".ply");
        const fs::path surface = test_dir() / ("surface_" + name + ".vdb");
        fs::remove(mesh);
        fs::remove(surface);

        const CliResult m = run("mesh " + damaged.string() + " -o " + mesh.string());
        expect_clear_failure(m, damaged.filename().string());
        if (!bytes.empty()) {  // an empty file has no offset to name
            EXPECT_NE(m.output.find("byte offset"), std::string::npos) << m.output;
        }
        EXPECT_FALSE(fs::exists(mesh));

        const CliResult b = run("bake " + damaged.string() + " -o " + surface.string());
        expect_clear_failure(b, damaged.filename().string());
        EXPECT_FALSE(fs::exists(surface));
    }
}

TEST(DamagedVdb, MeshRejectsDamagedSurfaces) {
    const std::string valid = read_bytes(mapped() / "surface.vdb");
    ASSERT_GT(valid.size(), 1000u);
    for (const auto& [name, bytes] : damaged_versions(valid, "class")) {
        SCOPED_TRACE(name);
        const fs::path damaged = test_dir() / ("surface_" + name + ".vdb");
        write_bytes(damaged, bytes);
        const fs::path mesh = test_dir() / ("mesh_" + name + ".ply");
        fs::remove(mesh);
        const CliResult m = run("mesh " + damaged.string() + " -o " + mesh.string());
        expect_clear_failure(m, damaged.filename().string());
        if (!bytes.empty()) {
            EXPECT_NE(m.output.find("byte offset"), std::string::npos) << m.output;
        }
        EXPECT_FALSE(fs::exists(mesh));
    }
}

TEST(DamagedVdb, ValidFilesStillWork) {
    for (const char* file : {"map.vdb", "surface.vdb"}) {
        SCOPED_TRACE(file);
        const fs::path mesh = test_dir() / (std::string(file) + ".ply");
        fs::remove(mesh);
        const CliResult m = run("mesh " + (mapped() / file).string() + " -o " + mesh.string());
        EXPECT_EQ(m.exit_code, 0) << m.output;
        EXPECT_TRUE(fs::exists(mesh));
    }
}
