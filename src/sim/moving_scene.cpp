#include "shine/sim/moving_scene.hpp"

#include <algorithm>
#include <limits>

#include "shine/sim/mesh_primitives.hpp"

namespace shine::sim {
namespace moving_scene_internal {

/// Distance from `point` to the segment [a, b].
double distance_to_segment(const Eigen::Vector3d& point, const Eigen::Vector3d& a,
                           const Eigen::Vector3d& b) {
    const Eigen::Vector3d ab = b - a;
    const double length2 = ab.squaredNorm();
    const double s = length2 > 0.0 ? std::clamp((point - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
    return (a + s * ab - point).norm();
}

/// Whether `mover`'s box comes within `radius_m` of `point_m` at some time in [begin_s, end_s]
/// while it is present. Conservative: the box is a sphere about its footprint's centre that
/// holds it.
bool reaches(const MoverTrack& mover, const Eigen::Vector3d& point_m, double radius_m,
             double begin_s, double end_s) {
    if (mover.waypoints.empty()) return false;
    const double from_s = std::max(begin_s, mover.waypoints.front().time_s);
    const double to_s = std::min(end_s, mover.waypoints.back().time_s);
    if (from_s > to_s) return false;
    const double body_radius_m =
        Eigen::Vector3d(0.5 * mover.size_m.x(), 0.5 * mover.size_m.y(), mover.size_m.z()).norm();
    // The path over [from_s, to_s]: its ends and the waypoints between them.
    Eigen::Vector3d previous = mover.T_world_body(from_s).translation();
    auto within = [&](const Eigen::Vector3d& next) {
        const bool near = distance_to_segment(point_m, previous, next) <= radius_m + body_radius_m;
        previous = next;
        return near;
    };
    for (const MoverWaypoint& w : mover.waypoints) {
        if (w.time_s > from_s && w.time_s < to_s && within(w.position_m)) return true;
    }
    return within(mover.T_world_body(to_s).translation());
}

}  // namespace moving_scene_internal

using namespace moving_scene_internal;

TriangleMesh make_mover_mesh(const MoverTrack& mover) {
    const Eigen::AlignedBox3d box = mover.box_body();
    return make_box_mesh(box.min().cast<float>(), box.max().cast<float>());
}

MovingScene::MovingScene(const RayCaster* static_mesh, const BlockRayCaster* static_blocks,
                         MoverTracks tracks)
    : static_mesh_(static_mesh), static_blocks_(static_blocks), tracks_(std::move(tracks)) {
    for (const MoverTrack& mover : tracks_.movers) {
        bodies_.push_back(std::make_unique<RayCaster>(make_mover_mesh(mover)));
    }
}

MovingScene::MovingScene(const RayCaster& static_scene, MoverTracks tracks)
    : MovingScene(&static_scene, nullptr, std::move(tracks)) {}

MovingScene::MovingScene(const BlockRayCaster& static_scene, MoverTracks tracks)
    : MovingScene(nullptr, &static_scene, std::move(tracks)) {}

std::size_t MovingScene::num_static_triangles() const {
    return static_mesh_ ? static_mesh_->num_triangles() : static_blocks_->num_triangles();
}

void MovingScene::cast_mover(std::size_t m, const Eigen::Vector3d& origin_m,
                             const Eigen::Vector3d& direction_unit, double t_min_m, double t_max_m,
                             double time_s, RayHit& best) const {
    const MoverTrack& mover = tracks_.movers[m];
    if (!mover.present(time_s)) return;
    // The ray in the body's frame at time_s: a rotation keeps the direction unit and the
    // distances in metres.
    const Eigen::Isometry3d T_body_world = mover.T_world_body(time_s).inverse();
    const double limit_m = best.hit() ? best.distance_m : t_max_m;
    const RayHit hit = bodies_[m]->cast(T_body_world * origin_m,
                                        T_body_world.linear() * direction_unit, t_min_m, limit_m);
    if (hit.hit() && hit.distance_m < limit_m) {
        best.distance_m = hit.distance_m;
        best.triangle_id = static_cast<std::int32_t>(num_static_triangles() + m);
    }
}

RayHit MovingScene::cast(const Eigen::Vector3d& origin_m, const Eigen::Vector3d& direction_unit,
                         double t_min_m, double t_max_m, double time_s) const {
    RayHit best = static_mesh_ ? static_mesh_->cast(origin_m, direction_unit, t_min_m, t_max_m)
                               : static_blocks_->cast(origin_m, direction_unit, t_min_m, t_max_m);
    for (std::size_t m = 0; m < bodies_.size(); ++m) {
        cast_mover(m, origin_m, direction_unit, t_min_m, t_max_m, time_s, best);
    }
    return best;
}

MovingSceneSelection MovingScene::select(const Eigen::Vector3d& point_m, double radius_m,
                                         double begin_s, double end_s) const {
    MovingSceneSelection selection;
    selection.scene_ = this;
    if (static_blocks_) selection.blocks_ = static_blocks_->select(point_m, radius_m);
    for (std::size_t m = 0; m < tracks_.movers.size(); ++m) {
        if (reaches(tracks_.movers[m], point_m, radius_m, begin_s, end_s)) {
            selection.movers_.push_back(m);
        }
    }
    return selection;
}

RayHit MovingSceneSelection::cast(const Eigen::Vector3d& origin_m,
                                  const Eigen::Vector3d& direction_unit, double t_min_m,
                                  double t_max_m, double time_s) const {
    RayHit best = scene_->static_mesh_
                      ? scene_->static_mesh_->cast(origin_m, direction_unit, t_min_m, t_max_m)
                      : blocks_.cast(origin_m, direction_unit, t_min_m, t_max_m);
    for (const std::size_t m : movers_) {
        scene_->cast_mover(m, origin_m, direction_unit, t_min_m, t_max_m, time_s, best);
    }
    return best;
}

}  // namespace shine::sim
