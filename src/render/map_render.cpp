#include "shine/render/map_render.hpp"

#include <tbb/parallel_for.h>

#include <cmath>
#include <limits>

#include "shine/core/error.hpp"

namespace shine {
namespace {
const TriangleMesh& checked(const TriangleMesh& mesh) {
    if (mesh.triangles.empty()) {
        throw DataError("the map's mesh has no triangles: nothing to render");
    }
    return mesh;
}
}  // namespace

MeshRenderer::MeshRenderer(const TriangleMesh& mesh) : mesh_(checked(mesh)), caster_(mesh) {}

ExrImage MeshRenderer::render(const PixelRays& rays, const Eigen::Isometry3d& T_world_sensor,
                              const MapRenderConfig& config) const {
    if (rays.directions_sensor.size() != rays.num_pixels() ||
        (!rays.measured_range_m.empty() && rays.measured_range_m.size() != rays.num_pixels())) {
        throw DataError("pixel rays do not match their " + std::to_string(rays.width) + " x " +
                        std::to_string(rays.height) + " image");
    }
    ExrImage image(rays.width, rays.height);
    const std::size_t n = rays.num_pixels();
    constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
    std::vector<float> range(n, kNaN), nx(n, kNaN), ny(n, kNaN), nz(n, kNaN);
    // The sensor in the mesh's frame, in double: world poses may be UTM-sized.
    const Eigen::Vector3d sensor_mesh = T_world_sensor.translation() - mesh_.origin_world_m;
    const Eigen::Matrix3d R_world_sensor = T_world_sensor.linear();
    tbb::parallel_for(0, rays.height, [&](int row) {
        for (int col = 0; col < rays.width; ++col) {
            const std::size_t i = std::size_t(row) * rays.width + col;
            const Eigen::Vector3d direction = R_world_sensor * rays.directions_sensor[i];
            const RayHit hit = caster_.cast(sensor_mesh, direction, 0.0, config.max_range_m);
            if (!hit.hit()) continue;
            range[i] = static_cast<float>(hit.distance_m);
            const Eigen::Vector3i& t = mesh_.triangles[hit.triangle_id];
            const Eigen::Vector3d a = mesh_.vertices[t[0]].cast<double>();
            const Eigen::Vector3d b = mesh_.vertices[t[1]].cast<double>();
            const Eigen::Vector3d c = mesh_.vertices[t[2]].cast<double>();
            Eigen::Vector3d normal = (b - a).cross(c - a);
            if (!(normal.norm() > 0.0)) continue;
            normal.normalize();
            if (normal.dot(direction) > 0.0) normal = -normal;  // face the sensor
            nx[i] = static_cast<float>(normal.x());
            ny[i] = static_cast<float>(normal.y());
            nz[i] = static_cast<float>(normal.z());
        }
    });
    if (!rays.measured_range_m.empty()) {
        std::vector<float> error(n, kNaN);
        for (std::size_t i = 0; i < n; ++i) {
            error[i] = rays.measured_range_m[i] - range[i];  // NaN if either is NaN
        }
        image.add_channel("range.V", std::move(range));
        image.add_channel("normal.X", std::move(nx));
        image.add_channel("normal.Y", std::move(ny));
        image.add_channel("normal.Z", std::move(nz));
        image.add_channel("measured.V", rays.measured_range_m);
        image.add_channel("error.V", std::move(error));
    } else {
        image.add_channel("range.V", std::move(range));
        image.add_channel("normal.X", std::move(nx));
        image.add_channel("normal.Y", std::move(ny));
        image.add_channel("normal.Z", std::move(nz));
    }
    image.attributes["shine_units"] = "range, measured, error: metres; normal: unit, world frame";
    return image;
}

}  // namespace shine
