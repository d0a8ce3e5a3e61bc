// libFuzzer target: PLY meshes and point clouds (ascii, binary little and big endian), with
// per-point times.
#include "fuzz_common.hpp"
#include "shine/io/ply.hpp"
#include "shine/io/point_intensity.hpp"
#include "shine/io/preprocess.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string_view bytes = shine_fuzz::as_view(data, size);
    shine_fuzz::expect_value_or_error([&] {
        const shine::TriangleMesh mesh = shine::parse_ply_mesh(bytes, shine_fuzz::kSource);
        // The reader promises triangles that index existing vertices, and finite vertices.
        for (const auto& t : mesh.triangles) {
            for (int k = 0; k < 3; ++k) {
                if (t[k] < 0 || static_cast<std::size_t>(t[k]) >= mesh.vertices.size()) {
                    std::abort();
                }
            }
        }
        for (const auto& v : mesh.vertices) {
            if (!v.allFinite()) std::abort();
        }
        if (!mesh.face_observed.empty() && mesh.face_observed.size() != mesh.triangles.size()) {
            std::abort();
        }
    });
    shine_fuzz::expect_value_or_error([&] {
        const auto points = shine::parse_ply_points(bytes, shine_fuzz::kSource);
        shine::preprocess_scan(points, shine::PreprocessConfig{}, shine_fuzz::kSource);
    });
    shine_fuzz::expect_value_or_error([&] {
        // Scans with per-point times: one time per point, or none.
        const shine::TimedPoints scan = shine::parse_ply_scan(bytes, shine_fuzz::kSource);
        if (!scan.point_time_s.empty() && scan.point_time_s.size() != scan.points_sensor.size()) {
            std::abort();
        }
        // Intensities likewise, and an empty list is the only "none".
        if (!scan.intensity.empty() && (scan.intensity.size() != scan.points_sensor.size() ||
                                        !shine::intensity_measured(scan.intensity))) {
            std::abort();
        }
    });
    return 0;
}
