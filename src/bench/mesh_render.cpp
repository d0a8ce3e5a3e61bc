#include "shine/bench/mesh_render.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "shine/core/error.hpp"

namespace shine {

Rgb error_colour(double value, double max_value) {
    const double t = max_value > 0.0 ? std::clamp(value / max_value, 0.0, 1.0) : 1.0;
    // Three stops: (190, 205, 225) -> (245, 205, 60) -> (215, 40, 35).
    const double stops[3][3] = {{190, 205, 225}, {245, 205, 60}, {215, 40, 35}};
    const double s = t * 2.0;
    const int i = std::min(1, static_cast<int>(s));
    const double f = s - i;
    Rgb c;
    c.r = static_cast<std::uint8_t>(std::lround(stops[i][0] + f * (stops[i + 1][0] - stops[i][0])));
    c.g = static_cast<std::uint8_t>(std::lround(stops[i][1] + f * (stops[i + 1][1] - stops[i][1])));
    c.b = static_cast<std::uint8_t>(std::lround(stops[i][2] + f * (stops[i + 1][2] - stops[i][2])));
    return c;
}

void render_mesh(RgbImage& image, int x0, int y0, int width, int height, const TriangleMesh& mesh,
                 const MeshRenderView& view, const std::vector<Rgb>& vertex_colours,
                 Rgb base_colour) {
    if (!vertex_colours.empty() && vertex_colours.size() != mesh.vertices.size()) {
        throw DataError("render_mesh: " + std::to_string(vertex_colours.size()) +
                        " vertex colours for " + std::to_string(mesh.vertices.size()) +
                        " vertices");
    }
    for (const auto& t : mesh.triangles) {
        for (int c = 0; c < 3; ++c) {
            if (t[c] < 0 || static_cast<std::size_t>(t[c]) >= mesh.vertices.size()) {
                throw DataError("render_mesh: a triangle refers to missing vertex " +
                                std::to_string(t[c]));
            }
        }
    }
    if (width < 1 || height < 1) return;

    // Camera basis: `forward` from the camera into the scene, `right` horizontal, `up` = right x f.
    const double az = view.azimuth_deg * M_PI / 180.0, el = view.elevation_deg * M_PI / 180.0;
    const Eigen::Vector3d to_camera(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az),
                                    std::sin(el));
    const Eigen::Vector3d forward = -to_camera;
    Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ());
    if (right.norm() < 1e-6) right = Eigen::Vector3d::UnitX();  // straight down
    right.normalize();
    const Eigen::Vector3d up = right.cross(forward).normalized();
    // Light from above, over the viewer's left shoulder.
    const Eigen::Vector3d light = (to_camera + 0.6 * up - 0.4 * right).normalized();

    Eigen::AlignedBox3f bounds = view.bounds;
    if (bounds.isEmpty()) {
        for (const auto& v : mesh.vertices) bounds.extend(v);
    }
    if (bounds.isEmpty()) return;
    double u_min = std::numeric_limits<double>::infinity(), u_max = -u_min;
    double v_min = u_min, v_max = -u_min;
    for (int corner = 0; corner < 8; ++corner) {
        const Eigen::Vector3d p =
            bounds.corner(static_cast<Eigen::AlignedBox3f::CornerType>(corner)).cast<double>();
        u_min = std::min(u_min, p.dot(right));
        u_max = std::max(u_max, p.dot(right));
        v_min = std::min(v_min, p.dot(up));
        v_max = std::max(v_max, p.dot(up));
    }
    const double scale = 0.96 * std::min(width / std::max(u_max - u_min, 1e-9),
                                         height / std::max(v_max - v_min, 1e-9));
    const double u_mid = 0.5 * (u_min + u_max), v_mid = 0.5 * (v_min + v_max);

    std::vector<Eigen::Vector3d> screen(mesh.vertices.size());  // pixel x, pixel y, depth
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i) {
        const Eigen::Vector3d p = mesh.vertices[i].cast<double>();
        screen[i] = {0.5 * width + (p.dot(right) - u_mid) * scale,
                     0.5 * height - (p.dot(up) - v_mid) * scale, p.dot(forward)};
    }
    std::vector<float> depth(static_cast<std::size_t>(width) * height,
                             std::numeric_limits<float>::infinity());
    for (const auto& t : mesh.triangles) {
        const Eigen::Vector3d &a = screen[t[0]], &b = screen[t[1]], &c = screen[t[2]];
        const double area = (b.x() - a.x()) * (c.y() - a.y()) - (b.y() - a.y()) * (c.x() - a.x());
        if (std::abs(area) < 1e-12) continue;
        const Eigen::Vector3d pa = mesh.vertices[t[0]].cast<double>();
        const Eigen::Vector3d n = (mesh.vertices[t[1]].cast<double>() - pa)
                                      .cross(mesh.vertices[t[2]].cast<double>() - pa);
        const double n_norm = n.norm();
        if (!(n_norm > 0.0)) continue;
        const double shade = 0.3 + 0.7 * std::abs(n.dot(light)) / n_norm;
        Rgb colour = base_colour;
        if (!vertex_colours.empty()) {
            const Rgb &ca = vertex_colours[t[0]], &cb = vertex_colours[t[1]],
                      &cc = vertex_colours[t[2]];
            colour = {static_cast<std::uint8_t>((ca.r + cb.r + cc.r) / 3),
                      static_cast<std::uint8_t>((ca.g + cb.g + cc.g) / 3),
                      static_cast<std::uint8_t>((ca.b + cb.b + cc.b) / 3)};
        }
        const Rgb shaded{static_cast<std::uint8_t>(std::lround(colour.r * shade)),
                         static_cast<std::uint8_t>(std::lround(colour.g * shade)),
                         static_cast<std::uint8_t>(std::lround(colour.b * shade))};
        const int px_lo =
            std::max(0, static_cast<int>(std::floor(std::min({a.x(), b.x(), c.x()}))));
        const int px_hi =
            std::min(width - 1, static_cast<int>(std::ceil(std::max({a.x(), b.x(), c.x()}))));
        const int py_lo =
            std::max(0, static_cast<int>(std::floor(std::min({a.y(), b.y(), c.y()}))));
        const int py_hi =
            std::min(height - 1, static_cast<int>(std::ceil(std::max({a.y(), b.y(), c.y()}))));
        for (int py = py_lo; py <= py_hi; ++py) {
            for (int px = px_lo; px <= px_hi; ++px) {
                const double x = px + 0.5, y = py + 0.5;
                // Barycentric coordinates; pixel centres on an edge count for both triangles, so
                // a watertight mesh leaves no cracks.
                const double w0 = ((b.x() - x) * (c.y() - y) - (b.y() - y) * (c.x() - x)) / area;
                const double w1 = ((c.x() - x) * (a.y() - y) - (c.y() - y) * (a.x() - x)) / area;
                const double w2 = 1.0 - w0 - w1;
                if (w0 < 0.0 || w1 < 0.0 || w2 < 0.0) continue;
                const float z = static_cast<float>(w0 * a.z() + w1 * b.z() + w2 * c.z());
                float& d = depth[static_cast<std::size_t>(py) * width + px];
                if (z >= d) continue;
                d = z;
                image.set(x0 + px, y0 + py, shaded);
            }
        }
    }
}

}  // namespace shine
