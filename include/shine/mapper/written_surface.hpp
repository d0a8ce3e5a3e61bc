// The level set and the mesh of a map's products as they were written to surface.vdb and
// mesh.ply, kept in memory for the steps that read them next (the surface's colour and
// reflectance, surface_appearance.hpp; then the scores against a reference and the held-out
// scans), so that they need not read the files back.
#pragma once

#include <openvdb/openvdb.h>

#include "shine/geometry/triangle_mesh.hpp"

namespace shine {

struct WrittenSurface {
    /// The grid surface.vdb holds; null once the appearance step has taken it over.
    openvdb::FloatGrid::Ptr level_set;
    /// What read_ply_mesh() gives back from mesh.ply (after the appearance step, with the
    /// colours and reflectance it wrote there).
    TriangleMesh mesh;
};

}  // namespace shine
