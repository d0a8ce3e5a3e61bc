#include "shine/sim/moving_scene.hpp"

#include "shine/sim/mesh_primitives.hpp"

namespace shine::sim {

TriangleMesh make_mover_mesh(const MoverTrack& mover) {
    const Eigen::AlignedBox3d box = mover.box_body();
    return make_box_mesh(box.min().cast<float>(), box.max().cast<float>());
}

MovingScene::MovingScene(const RayCaster& static_scene, MoverTracks tracks)
    : static_scene_(static_scene), tracks_(std::move(tracks)) {
    for (const MoverTrack& mover : tracks_.movers) {
        bodies_.push_back(std::make_unique<RayCaster>(make_mover_mesh(mover)));
    }
}

RayHit MovingScene::cast(const Eigen::Vector3d& origin_m, const Eigen::Vector3d& direction_unit,
                         double t_min_m, double t_max_m, double time_s) const {
    RayHit best = static_scene_.cast(origin_m, direction_unit, t_min_m, t_max_m);
    for (std::size_t m = 0; m < bodies_.size(); ++m) {
        // The ray in the body's frame at time_s: a rotation keeps the direction unit and the
        // distances in metres.
        const Eigen::Isometry3d T_body_world = tracks_.movers[m].T_world_body(time_s).inverse();
        const double limit_m = best.hit() ? best.distance_m : t_max_m;
        const RayHit hit = bodies_[m]->cast(
            T_body_world * origin_m, T_body_world.linear() * direction_unit, t_min_m, limit_m);
        if (hit.hit() && hit.distance_m < limit_m) {
            best.distance_m = hit.distance_m;
            best.triangle_id = static_cast<std::int32_t>(num_static_triangles() + m);
        }
    }
    return best;
}

}  // namespace shine::sim
