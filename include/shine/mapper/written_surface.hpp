// The level set and the mesh of a map's products as they were written to surface.vdb and
// mesh.ply, kept in memory for the step that reads them next (the surface's colour and
// reflectance, surface_appearance.hpp), so that it need not read the files back.
#pragma once

#include <openvdb/openvdb.h>

#include "shine/geometry/triangle_mesh.hpp"

namespace shine {

struct WrittenSurface {
    openvdb::FloatGrid::Ptr level_set;  ///< the grid surface.vdb holds
    TriangleMesh mesh;                  ///< what read_ply_mesh() gives back from mesh.ply
};

}  // namespace shine
