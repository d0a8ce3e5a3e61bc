// Colour and reflectance on a map's surface, added to the products of a mapped sequence: the
// last step of `shine map` when the scans carry intensity or the sequence folder holds camera
// images (io/camera_rig.hpp).
//
//   1. mesh.ply and surface.vdb are read back, or taken over from the step that wrote them (the
//      mesh is held whole here, unlike when meshing).
//   2. Colour (with images): every mapped scan's images, one at a time, are placed at the scan's
//      final pose (the refined one in batch mode), the mesh is rasterised into each (MeshRaster)
//      and the mesh's vertex colours are fitted to the pixels (vertex_colour_fit.hpp: least
//      squares; occlusion by the map's own surface; one exposure gain per image, the colours at
//      the images' mean exposure, the gains in the stats' `exposure`). Vertices no camera saw take
//      the mean colour of their coloured neighbours, ring by ring (up to fill_rings); the rest, out
//      of every camera's view, the mean colour of the seen ones (closer to what a camera would see
//      there than black: +0.1 dB on the real drive's held-out images).
//   3. Reflectance (scans with intensity): the points' intensities accumulated in voxels
//      (reflectance_voxels.hpp; batch mapping does it as it loads the scans, else every mapped
//      scan is read again and deskewed as for mapping) and read at the vertices.
//   4. mesh.ply gets per-vertex red, green, blue and intensity; surface.vdb the grids "color" and
//      "intensity" on the voxels next to the vertices (surface_attribute_grids.hpp; the colour
//      grid only where a camera saw the surface or a neighbour's colour reached it). Both files
//      are rewritten atomically.
// A sequence with neither leaves the products untouched, byte for byte.
#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>

#include "shine/colour/camera_exposure.hpp"
#include "shine/colour/reflectance_voxels.hpp"
#include "shine/colour/vertex_colour_fit.hpp"
#include "shine/io/camera_rig.hpp"
#include "shine/io/scan_sequence.hpp"
#include "shine/mapper/mapper_config.hpp"
#include "shine/mapper/written_surface.hpp"

namespace shine {

struct SurfaceAppearanceConfig {
    VertexColourFitConfig fit;
    double near_m = 0.3;  ///< triangles nearer a camera are left out of its z-buffer
    int fill_rings = 20;  ///< neighbour rings an unseen vertex may take its colour from
};

/// What add_surface_appearance() did.
struct SurfaceAppearanceStats {
    bool colour = false;     ///< colour was fused (the folder had images of mapped scans)
    bool intensity = false;  ///< reflectance was fused (the scans had intensity)
    std::size_t views = 0;   ///< images fused
    std::size_t vertices = 0;
    std::size_t coloured_vertices = 0;   ///< seen by at least one camera
    std::size_t filled_vertices = 0;     ///< coloured from their neighbours
    std::size_t coloured_voxels = 0;     ///< voxels of the colour grid
    std::size_t intensity_points = 0;    ///< scan points whose intensity was fused
    std::size_t intensity_vertices = 0;  ///< vertices with a reflectance
    std::size_t intensity_voxels = 0;    ///< voxels of the intensity grid
    ExposureTrack exposure;              ///< the fused images' exposure gains
    double seconds = 0.0;
};

/// Adds the intensities of `scan`'s points (at scan.T_world_sensor, as mapping placed them) with
/// ranges inside preprocess's to `voxels`, in the map frame at `origin_world_m`. Nothing for a
/// scan without intensity.
void add_scan_reflectance(ReflectanceVoxels& voxels, const Scan& scan,
                          const Eigen::Vector3d& origin_world_m,
                          const PreprocessConfig& preprocess);

/// Adds colour and reflectance to OUT_DIR/mesh.ply and OUT_DIR/surface.vdb (see the file
/// comment) from the scans of `mapped` (at the poses the map was made at) and the cameras of
/// `rig` (none: reflectance only). Does nothing when there are no images of those scans and no
/// intensity. `reflectance_map`: the scans' intensities already accumulated (add_scan_reflectance,
/// in the map frame of mesh.ply, voxels of surface.vdb's size); null: read the scans again.
/// `written`: the level set and mesh those two files hold (write_map_products), taken over
/// instead of read back (null: read from OUT_DIR); the mesh is given back as mesh.ply then holds
/// it (with its colours and reflectance), the level set is not.
/// Throws IoError / DataError naming a broken image or file; the products are then left as they
/// were.
SurfaceAppearanceStats add_surface_appearance(
    const std::filesystem::path& out_dir, const ScanSequence& mapped, const MapperConfig& config,
    const std::optional<CameraRig>& rig, const SurfaceAppearanceConfig& appearance = {},
    const ReflectanceVoxels* reflectance_map = nullptr, WrittenSurface* written = nullptr);

/// Area-weighted unit vertex normals of `mesh` (zero for a vertex without triangles).
std::vector<Eigen::Vector3d> vertex_normals(const TriangleMesh& mesh);

/// Gives vertices with known 0 the mean colour of their known neighbours, ring by ring, at most
/// `rings` times, and marks them known; returns how many were filled.
std::size_t fill_unseen_colours(const TriangleMesh& mesh,
                                std::vector<std::array<std::uint8_t, 3>>& rgb,
                                std::vector<std::uint8_t>& known, int rings);

/// Gives vertices with known 0 the mean colour of the known ones (unchanged when none is known).
void fill_with_mean_colour(std::vector<std::array<std::uint8_t, 3>>& rgb,
                           const std::vector<std::uint8_t>& known);

}  // namespace shine
