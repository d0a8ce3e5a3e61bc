// The true colour of a simulated street: a procedural, unlit albedo (8-bit sRGB) for every point
// of every surface, so that colour fused from camera images onto a map can be checked against it.
//
// The colour is a pure function of what the surface is (the part's ScenePartSurface, its object's
// index, the triangle's outward normal) and the world point; nothing is random at run time and
// nothing depends on the view, so "what colour is the truth here" has one answer. It is textured
// so that recovering it is a real test, with features of about 1 m and a few of 0.1 m:
//   - road: dark asphalt; white lane markings: a dashed centre line (3 m dashes every 6 m, 0.15 m
//     wide) and solid lines 0.12 m wide between the driving lanes and the parking lanes;
//   - curb faces: concrete; sidewalks: pale paving slabs with darker joints on a 1 m grid;
//     lots (the ground beyond the sidewalks): grass;
//   - building walls: a colour per building from a palette of ten, with one of three patterns per
//     building: a window grid (storeys of 3 m, windows 1.2 m wide every 2 m), horizontal bands of
//     1 m, or brick courses (0.5 m, the colour alternating); flat roofs grey, gable roofs tiled
//     (terracotta or slate, 0.5 m courses), roof boxes light grey;
//   - cars: a saturated colour per car from a palette of nine, wheels near-black;
//   - trees: bark brown trunks, crowns in one of five greens per tree with a 0.5 m mottle;
//   - poles and lamp arms grey metal, lamp heads pale yellow; pedestrians: dark trousers, a
//     coloured top per person, skin-toned heads.
// Movers (io/mover_tracks.hpp) have one colour each (cars from the car palette, cyclists and
// pedestrians from their own), and rays that hit nothing see kSkyColour.
//
// Where patterns meet (a window's edge) the colour changes in a step, so a pixel or a map vertex
// on an edge may take either side; tests compare away from edges or with a tolerance.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "shine/core/png_image.hpp"
#include "shine/io/mover_tracks.hpp"
#include "shine/sim/street_scene.hpp"

namespace shine::sim {

/// The colour of rays that hit nothing (a clear sky).
inline constexpr Rgb kSkyColour{135, 185, 235};

/// The street's cross-section, which the ground's colours follow (lane markings, curbs,
/// sidewalks, lots). Lengths in metres; the street runs along world +x with its centre at y = 0.
struct StreetCrossSection {
    double half_road_m = 5.0;       ///< |y| of the curbs
    double sidewalk_outer_m = 8.0;  ///< |y| of the sidewalks' outer edges (the lots beyond)
    double curb_height_m = 0.15;    ///< the sidewalks' height above the road
};

/// The cross-section of the street make_street_scene(config) builds.
StreetCrossSection cross_section_of(const StreetSceneConfig& config);

/// What a colour is asked for: a point on a part of the scene.
struct SurfacePoint {
    ScenePartSurface surface = ScenePartSurface::kGround;  ///< what the part is
    std::size_t object_index = 0;  ///< ScenePart::object_index: picks the object's colour
    Eigen::Vector3d point_m = Eigen::Vector3d::Zero();  ///< world (the mesh's frame)
    Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< the triangle's outward unit normal
};

/// The albedo at a point of a street's surface (the file comment lists the patterns). A pure
/// function: the same arguments give the same colour on every machine.
Rgb surface_albedo(const SurfacePoint& point, const StreetCrossSection& street);

/// The colour of mover `mover_index` of a sequence (one colour per mover, from its kind).
Rgb mover_albedo(MoverKind kind, std::size_t mover_index);

/// The albedo of a built street looked up by triangle: finds the triangle's part (and so its
/// surface and object) and normal, and calls surface_albedo. Refers to `scene`, which must outlive
/// it; at() is thread-safe.
class SceneAlbedo {
  public:
    /// `scene` as make_street_scene(config) built it. Throws ConfigError if the scene's parts do
    /// not cover its triangles in order.
    SceneAlbedo(const StreetScene& scene, const StreetSceneConfig& config);

    /// The albedo at `point_m` (world) on triangle `triangle_id` of the scene's mesh (e.g. a
    /// RayCaster hit's triangle_id and origin + distance * direction). Throws ConfigError for a
    /// triangle id outside the mesh.
    Rgb at(std::int32_t triangle_id, const Eigen::Vector3d& point_m) const;

    /// The SurfacePoint at() colours: the triangle's part surface, object and outward normal.
    SurfacePoint surface_point(std::int32_t triangle_id, const Eigen::Vector3d& point_m) const;

    /// The part triangle `triangle_id` belongs to. Throws ConfigError outside the mesh.
    const ScenePart& part_of(std::int32_t triangle_id) const;

    const StreetCrossSection& cross_section() const { return street_; }

  private:
    const StreetScene* scene_;
    StreetCrossSection street_;
};

}  // namespace shine::sim
