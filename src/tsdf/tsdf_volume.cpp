#include "shine/tsdf/tsdf_volume.hpp"

#include <openvdb/math/DDA.h>
#include <openvdb/math/Ray.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "shine/core/error.hpp"

namespace shine {

void TsdfConfig::validate() const {
    if (!(voxel_size_m > 0.0) || !std::isfinite(voxel_size_m)) {
        throw ConfigError("--voxel-size-m = " + std::to_string(voxel_size_m) +
                          " must be a positive number of metres (VDBFusion uses 0.1)");
    }
    if (!(trunc_m > 0.0) || !std::isfinite(trunc_m)) {
        throw ConfigError("--trunc-m = " + std::to_string(trunc_m) +
                          " must be a positive number of metres (VDBFusion uses 3 voxels, 0.3)");
    }
}

float point_sdf_m(const Eigen::Vector3d& origin, const Eigen::Vector3d& point,
                  const Eigen::Vector3d& centre) {
    const Eigen::Vector3d origin_to_centre = centre - origin;
    const Eigen::Vector3d centre_to_point = point - centre;
    const double distance = centre_to_point.norm();
    return static_cast<float>(origin_to_centre.dot(centre_to_point) < 0.0 ? -distance : distance);
}

namespace {
openvdb::FloatGrid::Ptr make_grid(float background, const char* name) {
    openvdb::initialize();
    auto grid = openvdb::FloatGrid::create(background);
    grid->setName(name);
    return grid;
}

float tsdf_background(const TsdfConfig& config) {
    // VDBFusion: +trunc, negated with space carving (unobserved space then reads as occupied
    // when fill_holes lets the mesher use it).
    const auto trunc = static_cast<float>(config.trunc_m);
    return config.space_carving ? -trunc : trunc;
}
}  // namespace

TsdfVolume::TsdfVolume(const TsdfConfig& config, const Eigen::Vector3d& origin_world_m)
    : config_(config), origin_world_m_(origin_world_m) {
    config_.validate();
    tsdf_ = make_grid(tsdf_background(config_), "tsdf");
    tsdf_->setGridClass(openvdb::GRID_LEVEL_SET);
    weight_ = make_grid(0.0f, "weight");
    weight_->setGridClass(openvdb::GRID_UNKNOWN);
    update_transforms();
}

TsdfVolume::TsdfVolume(const TsdfConfig& config, const Eigen::Vector3d& origin_world_m,
                       openvdb::FloatGrid::Ptr tsdf, openvdb::FloatGrid::Ptr weight)
    : config_(config),
      origin_world_m_(origin_world_m),
      tsdf_(std::move(tsdf)),
      weight_(std::move(weight)) {
    config_.validate();
    if (!tsdf_ || !weight_) throw DataError("TSDF volume: missing tsdf or weight grid");
    for (const auto* grid : {tsdf_.get(), weight_.get()}) {
        const openvdb::Vec3d size = grid->voxelSize();
        const double tolerance = 1e-9 * config_.voxel_size_m;
        if (!grid->transform().isLinear() || std::abs(size[0] - config_.voxel_size_m) > tolerance ||
            std::abs(size[1] - config_.voxel_size_m) > tolerance ||
            std::abs(size[2] - config_.voxel_size_m) > tolerance) {
            throw DataError("TSDF volume: grid '" + grid->getName() + "' has voxel size " +
                            std::to_string(size[0]) + ", expected " +
                            std::to_string(config_.voxel_size_m) + " m in every axis");
        }
    }
    if (tsdf_->background() != tsdf_background(config_) || weight_->background() != 0.0f) {
        throw DataError("TSDF volume: grid backgrounds (" + std::to_string(tsdf_->background()) +
                        ", " + std::to_string(weight_->background()) +
                        ") do not match the truncation and carving settings");
    }
    update_transforms();
}

void TsdfVolume::update_transforms() {
    // Index (i, j, k) -> world centre origin + ((i, j, k) + 1/2) * voxel_size_m, so OpenVDB tools
    // (vdb_print, Blender, volumeToMesh) place the voxels where they were measured. VDBFusion
    // itself stores a plain scale, half a voxel off from the centres it integrates at.
    auto transform = openvdb::math::Transform::createLinearTransform(config_.voxel_size_m);
    const Eigen::Vector3d shift =
        origin_world_m_ + Eigen::Vector3d::Constant(0.5 * config_.voxel_size_m);
    transform->postTranslate(openvdb::Vec3d(shift.x(), shift.y(), shift.z()));
    tsdf_->setTransform(transform);
    weight_->setTransform(transform->copy());
}

void TsdfVolume::set_origin_world_m(const Eigen::Vector3d& origin_world_m) {
    if (!empty()) {
        throw std::logic_error("TsdfVolume::set_origin_world_m on a volume that holds data");
    }
    origin_world_m_ = origin_world_m;
    update_transforms();
}

openvdb::Coord TsdfVolume::voxel_of(const Eigen::Vector3d& point_map) const {
    const Eigen::Vector3d index = point_map / config_.voxel_size_m;
    return openvdb::Coord(static_cast<int>(std::floor(index.x())),
                          static_cast<int>(std::floor(index.y())),
                          static_cast<int>(std::floor(index.z())));
}

Eigen::Vector3d TsdfVolume::voxel_centre_map(const openvdb::Coord& voxel) const {
    return (Eigen::Vector3d(voxel.x(), voxel.y(), voxel.z()) + Eigen::Vector3d::Constant(0.5)) *
           config_.voxel_size_m;
}

float TsdfVolume::tsdf(const openvdb::Coord& voxel) const { return tsdf_->tree().getValue(voxel); }

float TsdfVolume::weight(const openvdb::Coord& voxel) const {
    return weight_->tree().getValue(voxel);
}

std::size_t TsdfVolume::active_voxels() const {
    return static_cast<std::size_t>(weight_->activeVoxelCount());
}

std::size_t TsdfVolume::tsdf_memory_bytes() const {
    return static_cast<std::size_t>(tsdf_->memUsage());
}

std::size_t TsdfVolume::weight_memory_bytes() const {
    return static_cast<std::size_t>(weight_->memUsage());
}

std::size_t TsdfVolume::integrate(const std::vector<Eigen::Vector3d>& points_map,
                                  const Eigen::Vector3d& sensor_origin_map) {
    if (!sensor_origin_map.allFinite()) {
        throw DataError("TSDF integration: the sensor origin is not finite");
    }
    using Ray = openvdb::math::Ray<double>;
    const double voxel_m = config_.voxel_size_m;
    const double trunc_m = config_.trunc_m;
    const auto trunc = static_cast<float>(trunc_m);
    const Eigen::Vector3d eye_index = sensor_origin_map / voxel_m;
    auto tsdf = tsdf_->getAccessor();
    auto weight = weight_->getAccessor();
    std::size_t updates = 0;
    for (const Eigen::Vector3d& point : points_map) {
        if (!point.allFinite()) continue;
        const Eigen::Vector3d ray = point - sensor_origin_map;
        const double depth_m = ray.norm();
        if (!(depth_m > 0.0)) continue;
        const Eigen::Vector3d direction = ray / depth_m;
        const double t0_m = config_.space_carving ? 0.0 : depth_m - trunc_m;
        const double t1_m = depth_m + trunc_m;
        // The ray in index space (VDBFusion's Ray::worldToIndex): same unit direction, times in
        // voxels. The DDA visits every voxel whose entry time is <= t1, starting with the voxel
        // that contains the point at t0.
        const Ray index_ray(Ray::Vec3Type(eye_index.x(), eye_index.y(), eye_index.z()),
                            Ray::Vec3Type(direction.x(), direction.y(), direction.z()),
                            t0_m / voxel_m, t1_m / voxel_m);
        openvdb::math::DDA<Ray> dda(index_ray);
        do {
            const openvdb::Coord& voxel = dda.voxel();
            const float sdf = point_sdf_m(sensor_origin_map, point, voxel_centre_map(voxel));
            if (sdf > -trunc) {
                const float value = std::min(trunc, sdf);
                const float last_weight = weight.getValue(voxel);
                const float last_tsdf = tsdf.getValue(voxel);
                const float new_weight = last_weight + 1.0f;
                tsdf.setValue(voxel, (last_tsdf * last_weight + value) / new_weight);
                weight.setValue(voxel, new_weight);
                ++updates;
            }
        } while (dda.step());
    }
    return updates;
}

}  // namespace shine
