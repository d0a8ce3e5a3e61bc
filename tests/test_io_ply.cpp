#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <string>

#include "shine/core/error.hpp"
#include "shine/io/ply.hpp"

namespace fs = std::filesystem;

namespace {

fs::path test_dir(const std::string& name) {
    const fs::path dir = fs::path(SHINE_TEST_TMP_DIR) / "io_ply" / name;
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

void write_bytes(const fs::path& path, const std::string& bytes) {
    std::ofstream out(path, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    ASSERT_TRUE(out.good());
}

/// Appends `value` to `out` in the requested byte order.
template <typename T>
void put(std::string& out, T value, bool big_endian) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    if (big_endian) {
        for (std::size_t i = 0; i < sizeof(T) / 2; ++i)
            std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
    }
    out.append(bytes, sizeof(T));
}

/// Expects `f` to throw IoError whose message names `path` and contains `fragment`.
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

shine::TriangleMesh random_mesh(std::size_t vertices, std::size_t triangles, bool observed) {
    std::mt19937 rng(42);
    std::uniform_real_distribution<float> coord(-100.0f, 100.0f);
    std::uniform_int_distribution<int> index(0, static_cast<int>(vertices) - 1);
    shine::TriangleMesh mesh;
    for (std::size_t i = 0; i < vertices; ++i)
        mesh.vertices.emplace_back(coord(rng), coord(rng), coord(rng));
    for (std::size_t i = 0; i < triangles; ++i) {
        mesh.triangles.emplace_back(index(rng), index(rng), index(rng));
        if (observed) mesh.face_observed.push_back(static_cast<std::uint8_t>(rng() % 2));
    }
    return mesh;
}

}  // namespace

TEST(PlyMesh, RoundTripWithObservedFlagsIsExact) {
    const fs::path path = test_dir("roundtrip") / "mesh.ply";
    const shine::TriangleMesh mesh = random_mesh(1000, 3000, /*observed=*/true);
    shine::write_ply_mesh(path, mesh);
    const shine::TriangleMesh back = shine::read_ply_mesh(path);
    ASSERT_EQ(back.vertices.size(), mesh.vertices.size());
    ASSERT_EQ(back.triangles.size(), mesh.triangles.size());
    ASSERT_EQ(back.face_observed.size(), mesh.face_observed.size());
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
        EXPECT_EQ(back.vertices[i], mesh.vertices[i]);
    for (std::size_t i = 0; i < mesh.triangles.size(); ++i) {
        EXPECT_EQ(back.triangles[i], mesh.triangles[i]);
        EXPECT_EQ(back.face_observed[i], mesh.face_observed[i]);
    }
}

TEST(PlyMesh, RoundTripWithoutObservedHasNoFlags) {
    const fs::path path = test_dir("no_observed") / "mesh.ply";
    const shine::TriangleMesh mesh = random_mesh(10, 20, /*observed=*/false);
    shine::write_ply_mesh(path, mesh);
    const shine::TriangleMesh back = shine::read_ply_mesh(path);
    EXPECT_TRUE(back.face_observed.empty());
    ASSERT_EQ(back.triangles.size(), 20u);
    EXPECT_EQ(back.triangles[7], mesh.triangles[7]);
}

TEST(PlyMesh, VertexColoursAndIntensityRoundTripExactly) {
    const fs::path path = test_dir("appearance") / "mesh.ply";
    shine::TriangleMesh mesh = random_mesh(300, 500, /*observed=*/false);
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        mesh.vertex_rgb.push_back({static_cast<std::uint8_t>(i),
                                   static_cast<std::uint8_t>(255 - i % 256),
                                   static_cast<std::uint8_t>(i * 7)});
        mesh.vertex_intensity.push_back(i % 10 == 0 ? std::nanf("")
                                                    : 0.01f * static_cast<float>(i));
    }
    shine::write_ply_mesh(path, mesh);
    const shine::TriangleMesh back = shine::read_ply_mesh(path);
    ASSERT_EQ(back.vertex_rgb.size(), mesh.vertices.size());
    ASSERT_EQ(back.vertex_intensity.size(), mesh.vertices.size());
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        EXPECT_EQ(back.vertices[i], mesh.vertices[i]);
        EXPECT_EQ(back.vertex_rgb[i], mesh.vertex_rgb[i]);
        if (i % 10 == 0) {
            EXPECT_TRUE(std::isnan(back.vertex_intensity[i]));
        } else {
            EXPECT_EQ(back.vertex_intensity[i], mesh.vertex_intensity[i]);
        }
    }
    EXPECT_EQ(back.triangles, mesh.triangles);
    // Without appearance the file stays what it was (no new properties).
    mesh.vertex_rgb.clear();
    mesh.vertex_intensity.clear();
    shine::write_ply_mesh(path, mesh);
    EXPECT_TRUE(shine::read_ply_mesh(path).vertex_rgb.empty());
    // A wrong count is refused and writes nothing.
    mesh.vertex_rgb.resize(3);
    EXPECT_THROW(shine::write_ply_mesh(test_dir("appearance_bad") / "mesh.ply", mesh),
                 shine::DataError);
    EXPECT_FALSE(fs::exists(test_dir("appearance_bad") / "mesh.ply"));
}

TEST(PlyMesh, ReadsColoursOfAnAsciiMeshWrittenByHand) {
    // The layout MeshLab and Open3D write: uchar red green blue (and alpha) after x y z.
    const fs::path path = test_dir("ascii_colours") / "mesh.ply";
    write_bytes(path,
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                "property float z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
                "property uchar alpha\nproperty float intensity\nelement face 1\n"
                "property list uchar int vertex_indices\nend_header\n"
                "0 0 0 255 0 0 255 0.5\n1 0 0 0 128 0 255 0.25\n0 1 0 1 2 3 255 7\n3 0 1 2\n");
    const shine::TriangleMesh mesh = shine::read_ply_mesh(path);
    ASSERT_EQ(mesh.vertex_rgb.size(), 3u);
    EXPECT_EQ(mesh.vertex_rgb[0], (std::array<std::uint8_t, 3>{255, 0, 0}));
    EXPECT_EQ(mesh.vertex_rgb[1], (std::array<std::uint8_t, 3>{0, 128, 0}));
    EXPECT_EQ(mesh.vertex_rgb[2], (std::array<std::uint8_t, 3>{1, 2, 3}));
    ASSERT_EQ(mesh.vertex_intensity.size(), 3u);
    EXPECT_EQ(mesh.vertex_intensity[2], 7.0f);
}

TEST(PlyMesh, EmptyMeshRoundTrips) {
    const fs::path path = test_dir("empty_mesh") / "mesh.ply";
    shine::write_ply_mesh(path, shine::TriangleMesh{});
    const shine::TriangleMesh back = shine::read_ply_mesh(path);
    EXPECT_TRUE(back.vertices.empty());
    EXPECT_TRUE(back.triangles.empty());
}

TEST(PlyMesh, WriteRejectsInconsistentMesh) {
    const fs::path dir = test_dir("write_invalid");
    shine::TriangleMesh mesh = random_mesh(5, 4, /*observed=*/true);
    mesh.face_observed.pop_back();
    EXPECT_THROW(shine::write_ply_mesh(dir / "a.ply", mesh), shine::DataError);
    mesh = random_mesh(5, 4, false);
    mesh.triangles[2] = Eigen::Vector3i(0, 1, 5);
    EXPECT_THROW(shine::write_ply_mesh(dir / "b.ply", mesh), shine::DataError);
    EXPECT_FALSE(fs::exists(dir / "a.ply"));
    EXPECT_FALSE(fs::exists(dir / "b.ply"));
}

TEST(PlyMesh, HalfAMillionTrianglesRoundTrip) {
    // Large enough to cross the writer's buffer many times; the write speed itself is a benchmark
    // matter (docs/performance.md), not a test's.
    const fs::path path = test_dir("large") / "big.ply";
    const shine::TriangleMesh mesh = random_mesh(250000, 500000, /*observed=*/true);
    shine::write_ply_mesh(path, mesh);
    // 12 bytes per vertex, 1 + 12 + 1 per face, plus the header.
    EXPECT_GT(fs::file_size(path), 250000u * 12 + 500000u * 14);
    const shine::TriangleMesh back = shine::read_ply_mesh(path);
    ASSERT_EQ(back.triangles.size(), mesh.triangles.size());
    EXPECT_EQ(back.triangles.back(), mesh.triangles.back());
    EXPECT_EQ(back.face_observed.back(), mesh.face_observed.back());
}

TEST(PlyMesh, ReadsAsciiWithPolygonsExtraPropertiesAndUnknownElements) {
    const fs::path path = test_dir("ascii") / "quad.ply";
    write_bytes(path,
                "ply\r\n"
                "format ascii 1.0\r\n"
                "comment made by hand\r\n"
                "obj_info nothing\r\n"
                "element vertex 5\r\n"
                "property double x\r\n"
                "property float nx\r\n"
                "property float y\r\n"
                "property list uchar int tags\r\n"
                "property float z\r\n"
                "element material 1\r\n"
                "property uchar red\r\n"
                "property list ushort float weights\r\n"
                "element face 2\r\n"
                "property list uchar uint vertex_indices\r\n"
                "property uchar observed\r\n"
                "property float quality\r\n"
                "end_header\r\n"
                "0 9 0 0 0\r\n"
                "1.5 9 0 2 7 8 0\r\n"
                "1 9 +1 1 3 0\r\n"
                "0 9 1 0 -2.5e-1\r\n"
                "0.5 9 0.5 0 1e0\r\n"
                "255 3 0.1 0.2 0.3\r\n"
                "4 0 1 2 3 1 0.5\r\n"
                "3 0 2 4 0 1\r\n");
    const shine::TriangleMesh mesh = shine::read_ply_mesh(path);
    ASSERT_EQ(mesh.vertices.size(), 5u);
    EXPECT_EQ(mesh.vertices[1], Eigen::Vector3f(1.5f, 0.0f, 0.0f));
    EXPECT_EQ(mesh.vertices[2], Eigen::Vector3f(1.0f, 1.0f, 0.0f));
    EXPECT_EQ(mesh.vertices[3], Eigen::Vector3f(0.0f, 1.0f, -0.25f));
    EXPECT_EQ(mesh.vertices[4], Eigen::Vector3f(0.5f, 0.5f, 1.0f));
    // The quad becomes the fan (0,1,2), (0,2,3); both inherit its observed flag.
    ASSERT_EQ(mesh.triangles.size(), 3u);
    EXPECT_EQ(mesh.triangles[0], Eigen::Vector3i(0, 1, 2));
    EXPECT_EQ(mesh.triangles[1], Eigen::Vector3i(0, 2, 3));
    EXPECT_EQ(mesh.triangles[2], Eigen::Vector3i(0, 2, 4));
    ASSERT_EQ(mesh.face_observed.size(), 3u);
    EXPECT_EQ(mesh.face_observed[0], 1);
    EXPECT_EQ(mesh.face_observed[1], 1);
    EXPECT_EQ(mesh.face_observed[2], 0);

    const auto points = shine::read_ply_points(path);
    ASSERT_EQ(points.size(), 5u);
    EXPECT_EQ(points[4], Eigen::Vector3f(0.5f, 0.5f, 1.0f));
}

TEST(PlyMesh, ReadsBigEndianWithUnknownElementBeforeFaces) {
    const fs::path path = test_dir("big_endian") / "mesh.ply";
    std::string bytes =
        "ply\n"
        "format binary_big_endian 1.0\n"
        "element vertex 4\n"
        "property double x\n"
        "property short label\n"
        "property double y\n"
        "property double z\n"
        "element edge 2\n"
        "property int vertex1\n"
        "property list uchar int path\n"
        "element face 1\n"
        "property char flags\n"
        "property list ushort uint vertex_indices\n"
        "property uchar observed\n"
        "end_header\n";
    const double coords[4][3] = {{0, 0, 0}, {1.25, -2, 3}, {1e6, 0.5, -7}, {-1, -1, -1}};
    for (int v = 0; v < 4; ++v) {
        put<double>(bytes, coords[v][0], true);
        put<std::int16_t>(bytes, static_cast<std::int16_t>(-v), true);
        put<double>(bytes, coords[v][1], true);
        put<double>(bytes, coords[v][2], true);
    }
    put<std::int32_t>(bytes, 3, true);
    put<std::uint8_t>(bytes, 2, true);
    put<std::int32_t>(bytes, 1, true);
    put<std::int32_t>(bytes, 2, true);
    put<std::int32_t>(bytes, 0, true);
    put<std::uint8_t>(bytes, 0, true);
    put<std::int8_t>(bytes, -1, true);
    put<std::uint16_t>(bytes, 4, true);
    for (std::uint32_t i : {3u, 2u, 1u, 0u}) put<std::uint32_t>(bytes, i, true);
    put<std::uint8_t>(bytes, 1, true);
    write_bytes(path, bytes);

    const shine::TriangleMesh mesh = shine::read_ply_mesh(path);
    ASSERT_EQ(mesh.vertices.size(), 4u);
    for (int v = 0; v < 4; ++v) {
        EXPECT_EQ(mesh.vertices[v],
                  Eigen::Vector3d(coords[v][0], coords[v][1], coords[v][2]).cast<float>());
    }
    ASSERT_EQ(mesh.triangles.size(), 2u);
    EXPECT_EQ(mesh.triangles[0], Eigen::Vector3i(3, 2, 1));
    EXPECT_EQ(mesh.triangles[1], Eigen::Vector3i(3, 1, 0));
    ASSERT_EQ(mesh.face_observed.size(), 2u);
    EXPECT_EQ(mesh.face_observed[1], 1);
}

/// Writes a one-vertex PLY whose coordinates have the given type name, in either byte order.
template <typename T>
void check_scalar_type(const std::string& type_name, bool big_endian) {
    SCOPED_TRACE(type_name + (big_endian ? " big-endian" : " little-endian"));
    const fs::path path = test_dir("types") / ("p_" + type_name + ".ply");
    std::string bytes =
        "ply\nformat " + std::string(big_endian ? "binary_big_endian" : "binary_little_endian") +
        " 1.0\nelement vertex 2\nproperty " + type_name + " x\nproperty " + type_name +
        " y\nproperty " + type_name + " z\nproperty " + type_name + " intensity\nend_header\n";
    const T values[2][4] = {{T(1), T(2), T(3), T(9)}, {T(100), T(0), T(7), T(0)}};
    for (const auto& v : values) {
        for (T c : v) put<T>(bytes, c, big_endian);
    }
    write_bytes(path, bytes);
    const auto points = shine::read_ply_points(path);
    ASSERT_EQ(points.size(), 2u);
    EXPECT_EQ(points[0], Eigen::Vector3f(1, 2, 3));
    EXPECT_EQ(points[1], Eigen::Vector3f(100, 0, 7));
    // The intensity property of the same type, as stored.
    const shine::TimedPoints scan = shine::read_ply_scan(path);
    EXPECT_EQ(scan.points_sensor, points);
    EXPECT_EQ(scan.intensity, (std::vector<float>{9.0f, 0.0f}));
    EXPECT_EQ(scan.intensity_field, "intensity");
}

TEST(PlyPoints, ReadsEveryScalarTypeInBothByteOrders) {
    for (bool big : {false, true}) {
        check_scalar_type<std::int8_t>("char", big);
        check_scalar_type<std::int8_t>("int8", big);
        check_scalar_type<std::uint8_t>("uchar", big);
        check_scalar_type<std::uint8_t>("uint8", big);
        check_scalar_type<std::int16_t>("short", big);
        check_scalar_type<std::int16_t>("int16", big);
        check_scalar_type<std::uint16_t>("ushort", big);
        check_scalar_type<std::uint16_t>("uint16", big);
        check_scalar_type<std::int32_t>("int", big);
        check_scalar_type<std::int32_t>("int32", big);
        check_scalar_type<std::uint32_t>("uint", big);
        check_scalar_type<std::uint32_t>("uint32", big);
        check_scalar_type<float>("float", big);
        check_scalar_type<float>("float32", big);
        check_scalar_type<double>("double", big);
        check_scalar_type<double>("float64", big);
    }
}

TEST(PlyPoints, IntensityByNameWithoutCaseInOrderOfPreference) {
    // CloudCompare's scalar_Intensity beside a `reflectance`: reflectance comes first.
    const std::string both =
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
        "property float z\nproperty float scalar_Intensity\nproperty uchar reflectance\n"
        "end_header\n1 2 3 0.5 17\n4 5 6 nan 0\n";
    shine::TimedPoints scan = shine::parse_ply_scan(both, "both.ply");
    EXPECT_EQ(scan.intensity, (std::vector<float>{17.0f, 0.0f}));
    EXPECT_EQ(scan.intensity_field, "reflectance");
    // scalar_Intensity alone: its NaN is kept with its point.
    const std::string alone =
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
        "property float z\nproperty float scalar_Intensity\nend_header\n1 2 3 0.5\n"
        "4 5 6 nan\n";
    scan = shine::parse_ply_scan(alone, "alone.ply");
    ASSERT_EQ(scan.intensity.size(), 2u);
    EXPECT_EQ(scan.intensity[0], 0.5f);
    EXPECT_TRUE(std::isnan(scan.intensity[1]));
    EXPECT_EQ(scan.intensity_field, "scalar_Intensity");
    // A list named intensity is not one value per point: an error naming the file.
    const fs::path path = test_dir("intensity_list") / "list.ply";
    write_bytes(path,
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                "property float z\nproperty list uchar float intensity\nend_header\n"
                "1 2 3 2 0.5 0.25\n");
    expect_io_error([&] { shine::read_ply_scan(path); }, path,
                    "intensity property 'intensity' is a list");
    // Meshes do not look for it.
    EXPECT_EQ(shine::read_ply_mesh(path).vertices.size(), 1u);
}

TEST(PlyPoints, RoundTripAndFacesIgnored) {
    const fs::path dir = test_dir("points");
    std::vector<Eigen::Vector3f> points = {{1, 2, 3}, {-4.5f, 0.125f, 1e-7f}, {3e7f, -3e7f, 0}};
    shine::write_ply_points(dir / "p.ply", points);
    EXPECT_EQ(shine::read_ply_points(dir / "p.ply"), points);
    // A point cloud file has no faces; reading it as a mesh gives vertices only.
    const shine::TriangleMesh mesh = shine::read_ply_mesh(dir / "p.ply");
    EXPECT_EQ(mesh.vertices, points);
    EXPECT_TRUE(mesh.triangles.empty());
    // A mesh file read as points gives its vertices.
    shine::write_ply_mesh(dir / "m.ply", random_mesh(7, 9, true));
    EXPECT_EQ(shine::read_ply_points(dir / "m.ply").size(), 7u);
}

TEST(PlyErrors, MissingEmptyAndNotPly) {
    const fs::path dir = test_dir("errors_basic");
    expect_io_error([&] { shine::read_ply_mesh(dir / "missing.ply"); }, dir / "missing.ply",
                    "does not exist");
    write_bytes(dir / "empty.ply", "");
    expect_io_error([&] { shine::read_ply_mesh(dir / "empty.ply"); }, dir / "empty.ply", "empty");
    write_bytes(dir / "garbage.ply", std::string("\x7f"
                                                 "ELF\x01\x02\x00garbage",
                                                 13));
    expect_io_error([&] { shine::read_ply_points(dir / "garbage.ply"); }, dir / "garbage.ply",
                    "line 1");
    write_bytes(dir / "noend.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n");
    expect_io_error([&] { shine::read_ply_mesh(dir / "noend.ply"); }, dir / "noend.ply",
                    "end_header");
    write_bytes(dir / "format.ply", "ply\nformat binary_middle_endian 1.0\nend_header\n");
    expect_io_error([&] { shine::read_ply_mesh(dir / "format.ply"); }, dir / "format.ply",
                    "line 2");
    write_bytes(dir / "type.ply",
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n");
    expect_io_error([&] { shine::read_ply_mesh(dir / "type.ply"); }, dir / "type.ply", "line 4");
    write_bytes(dir / "noxyz.ply",
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float "
                "y\nend_header\n1 2\n");
    expect_io_error([&] { shine::read_ply_mesh(dir / "noxyz.ply"); }, dir / "noxyz.ply", "z");
}

TEST(PlyErrors, TruncatedBinaryNamesByteOffset) {
    const fs::path dir = test_dir("errors_truncated");
    shine::write_ply_mesh(dir / "full.ply", random_mesh(100, 200, true));
    std::ifstream in(dir / "full.ply", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    // Cut inside the face list: the header's count check passes only if little is missing,
    // so cut just a few bytes to exercise the cursor's bounds check.
    write_bytes(dir / "cut_faces.ply", bytes.substr(0, bytes.size() - 3));
    expect_io_error([&] { shine::read_ply_mesh(dir / "cut_faces.ply"); }, dir / "cut_faces.ply",
                    "truncated");
    // Cut inside the vertices: caught by the size check against the header counts.
    write_bytes(dir / "cut_vertices.ply", bytes.substr(0, bytes.size() / 4));
    expect_io_error([&] { shine::read_ply_mesh(dir / "cut_vertices.ply"); },
                    dir / "cut_vertices.ply", "truncated");
}

TEST(PlyErrors, HugeHeaderCountsAreRejectedBeforeAllocating) {
    const fs::path dir = test_dir("errors_huge");
    write_bytes(dir / "huge.ply",
                "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000000\n"
                "property float x\nproperty float y\nproperty float z\nend_header\n0123456789AB");
    expect_io_error([&] { shine::read_ply_points(dir / "huge.ply"); }, dir / "huge.ply",
                    "4000000000000");
    write_bytes(
        dir / "huge_faces.ply",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 18446744073709551615\n"
        "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    expect_io_error([&] { shine::read_ply_mesh(dir / "huge_faces.ply"); }, dir / "huge_faces.ply",
                    "line 7");
    write_bytes(dir / "overflow.ply",
                "ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\nend_header\n");
    expect_io_error([&] { shine::read_ply_mesh(dir / "overflow.ply"); }, dir / "overflow.ply",
                    "line 3");
    // A list length in the data that is absurd must not be trusted either.
    std::string bytes =
        "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
        "property float y\nproperty float z\nelement face 1\n"
        "property list uint int vertex_indices\nend_header\n";
    for (int i = 0; i < 3; ++i) put<float>(bytes, 0.0f, false);
    put<std::uint32_t>(bytes, 4000000000u, false);
    write_bytes(dir / "huge_list.ply", bytes);
    expect_io_error([&] { shine::read_ply_mesh(dir / "huge_list.ply"); }, dir / "huge_list.ply",
                    "byte offset");
}

TEST(PlyErrors, AsciiNonNumbersAndBadIndicesNameTheLine) {
    const fs::path dir = test_dir("errors_ascii");
    const std::string header =
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";
    write_bytes(dir / "nan_token.ply", header + "0 0 0\n1 abc 0\n0 1 0\n3 0 1 2\n");
    expect_io_error([&] { shine::read_ply_mesh(dir / "nan_token.ply"); }, dir / "nan_token.ply",
                    "line 11: 'abc' is not a number");
    write_bytes(dir / "bad_index.ply", header + "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n");
    expect_io_error([&] { shine::read_ply_mesh(dir / "bad_index.ply"); }, dir / "bad_index.ply",
                    "out of range");
    write_bytes(dir / "neg_index.ply", header + "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n");
    expect_io_error([&] { shine::read_ply_mesh(dir / "neg_index.ply"); }, dir / "neg_index.ply",
                    "line 13");
    write_bytes(dir / "frac_index.ply", header + "0 0 0\n1 0 0\n0 1 0\n3 0 1.5 2\n");
    expect_io_error([&] { shine::read_ply_mesh(dir / "frac_index.ply"); }, dir / "frac_index.ply",
                    "not an integer");
    write_bytes(dir / "short.ply", header + "0 0 0\n1 0 0\n0 1 0\n3 0 1\n");
    expect_io_error([&] { shine::read_ply_mesh(dir / "short.ply"); }, dir / "short.ply",
                    "truncated");
}

TEST(PlyErrors, EveryTruncationAndByteFlipGivesIoErrorOrAMesh) {
    const fs::path dir = test_dir("fuzz");
    std::vector<std::string> files;
    shine::write_ply_mesh(dir / "bin.ply", random_mesh(6, 5, /*observed=*/true));
    std::ifstream in(dir / "bin.ply", std::ios::binary);
    files.emplace_back((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    files.push_back(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
        "end_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
    std::mt19937 rng(9);
    int failures = 0;
    for (const std::string& original : files) {
        // Every prefix, then random single-byte corruptions.
        std::vector<std::string> variants;
        for (std::size_t n = 0; n < original.size(); ++n) variants.push_back(original.substr(0, n));
        for (int k = 0; k < 300; ++k) {
            std::string v = original;
            v[rng() % v.size()] = static_cast<char>(rng() % 256);
            variants.push_back(v);
        }
        for (const std::string& v : variants) {
            write_bytes(dir / "variant.ply", v);
            try {
                const shine::TriangleMesh mesh = shine::read_ply_mesh(dir / "variant.ply");
                for (const auto& t : mesh.triangles) {
                    for (int c = 0; c < 3; ++c) {
                        ASSERT_LT(static_cast<std::size_t>(t[c]), mesh.vertices.size());
                    }
                }
            } catch (const shine::IoError& e) {
                ++failures;
                ASSERT_NE(std::string(e.what()).find("variant.ply"), std::string::npos);
            }
        }
    }
    // All strict prefixes are broken files; they must all have been reported.
    EXPECT_GE(failures, static_cast<int>(files[0].size() + files[1].size()) - 2);
}

TEST(PlyErrors, NonFiniteMeshVerticesNameTheVertexAndPlace) {
    const fs::path dir = test_dir("errors_nonfinite");
    write_bytes(dir / "nan_vertex.ply",
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                "property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                "end_header\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n");
    expect_io_error([&] { shine::read_ply_mesh(dir / "nan_vertex.ply"); }, dir / "nan_vertex.ply",
                    "line 11: vertex 1 has a non-finite coordinate");
    // The same file as a point cloud: NaN is a scan's "no return", returned for preprocess_scan.
    const auto points = shine::read_ply_points(dir / "nan_vertex.ply");
    ASSERT_EQ(points.size(), 3u);
    EXPECT_TRUE(std::isnan(points[1].y()));

    std::string bytes =
        "ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n"
        "property float y\nproperty float z\nend_header\n";
    const std::size_t header_bytes = bytes.size();
    for (float c : {1.0f, 2.0f, 3.0f, 4.0f, std::numeric_limits<float>::infinity(), 6.0f}) {
        put<float>(bytes, c, false);
    }
    write_bytes(dir / "inf_vertex.ply", bytes);
    expect_io_error([&] { shine::read_ply_mesh(dir / "inf_vertex.ply"); }, dir / "inf_vertex.ply",
                    "byte offset " + std::to_string(header_bytes + 12) + ": vertex 1");
}

TEST(PlyErrors, AsciiDataBeyondTheDeclaredCountsIsRejected) {
    const fs::path dir = test_dir("errors_counts");
    // Four vertex lines for a header that declares three: the fourth would be read as a face.
    write_bytes(dir / "extra_vertex.ply",
                "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n");
    expect_io_error([&] { shine::read_ply_points(dir / "extra_vertex.ply"); },
                    dir / "extra_vertex.ply", "line 11: '0 0 1\\x0a' after the last element");
    expect_io_error([&] { shine::read_ply_mesh(dir / "extra_vertex.ply"); },
                    dir / "extra_vertex.ply", "more values than the header's element counts");
    // Fewer lines than declared.
    write_bytes(dir / "missing_vertex.ply",
                "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
                "property float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n");
    expect_io_error([&] { shine::read_ply_points(dir / "missing_vertex.ply"); },
                    dir / "missing_vertex.ply", "truncated");
    // Binary: a header declaring 10^12 vertices fails at once, naming the header line.
    write_bytes(dir / "tera.ply",
                "ply\nformat binary_little_endian 1.0\ncomment x\nelement vertex 1000000000000\n"
                "property float x\nproperty float y\nproperty float z\nend_header\n0123456789AB");
    const auto start = std::chrono::steady_clock::now();
    expect_io_error([&] { shine::read_ply_points(dir / "tera.ply"); }, dir / "tera.ply",
                    "line 4: header declares 1000000000000 'vertex' entries");
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 1.0);
}

TEST(PlyErrors, HeaderGarbageIsQuotedPrintably) {
    const fs::path dir = test_dir("errors_garbage");
    write_bytes(dir / "keyword.ply", "ply\nformat ascii 1.0\n\x01\x02\xfe stuff\n");
    expect_io_error([&] { shine::read_ply_points(dir / "keyword.ply"); }, dir / "keyword.ply",
                    "line 3: unknown header keyword '\\x01\\x02\\xfe'");
    write_bytes(dir / "no_format.ply", "ply\ncomment a\nelement vertex 0\nend_header\n");
    expect_io_error([&] { shine::read_ply_points(dir / "no_format.ply"); }, dir / "no_format.ply",
                    "header (lines 1-4): has no 'format' line");
    write_bytes(dir / "no_vertex.ply", "ply\nformat ascii 1.0\nelement face 0\nend_header\n");
    expect_io_error([&] { shine::read_ply_points(dir / "no_vertex.ply"); }, dir / "no_vertex.ply",
                    "header (lines 1-4): has no 'vertex' element");
}

TEST(PlyPoints, ParsesBytesInMemory) {
    const std::string text =
        "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
        "property float z\nend_header\n1 2 3\n4 5 6\n";
    const auto points = shine::parse_ply_points(text, "memory.ply");
    ASSERT_EQ(points.size(), 2u);
    EXPECT_EQ(points[1], Eigen::Vector3f(4, 5, 6));
    EXPECT_EQ(shine::parse_ply_mesh(text, "memory.ply").vertices, points);
}

TEST(PlyMesh, OriginOfFarAwayMeshesRoundTripsInTheHeader) {
    const fs::path dir = test_dir("origin");
    shine::TriangleMesh mesh = random_mesh(10, 5, /*observed=*/false);
    mesh.origin_world_m = Eigen::Vector3d(500000.125, 5000000.0625, -12.5);
    shine::write_ply_mesh(dir / "far.ply", mesh);
    const shine::TriangleMesh back = shine::read_ply_mesh(dir / "far.ply");
    EXPECT_EQ(back.origin_world_m, mesh.origin_world_m);  // exact: printed with 17 digits
    ASSERT_EQ(back.vertices.size(), mesh.vertices.size());
    EXPECT_EQ(back.vertices[3], mesh.vertices[3]);
    // Near the world origin nothing changes: no comment, zero origin.
    shine::write_ply_mesh(dir / "near.ply", random_mesh(10, 5, false));
    std::ifstream near(dir / "near.ply", std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(near)), {});
    EXPECT_EQ(text.find("shine_origin_world_m"), std::string::npos);
    EXPECT_EQ(shine::read_ply_mesh(dir / "near.ply").origin_world_m, Eigen::Vector3d::Zero());
}

TEST(PlyMesh, MalformedOriginCommentNamesTheLine) {
    const fs::path path = test_dir("bad_origin") / "mesh.ply";
    write_bytes(path,
                "ply\nformat ascii 1.0\ncomment shine_origin_world_m 1 nan 3\n"
                "element vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
                "end_header\n");
    expect_io_error([&] { shine::read_ply_mesh(path); }, path, "line 3");
    write_bytes(path,
                "ply\nformat ascii 1.0\ncomment shine_origin_world_m 1 2\n"
                "element vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
                "end_header\n");
    expect_io_error([&] { shine::read_ply_mesh(path); }, path, "line 3");
}
