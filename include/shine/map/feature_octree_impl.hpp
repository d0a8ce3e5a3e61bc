// OpenVDB internals of FeatureOctree, shared only by the map module's own sources (octree,
// serialisation, baking masks). Nothing outside src/neural includes this header.
#pragma once

#include <openvdb/openvdb.h>

#include <vector>

namespace shine {

/// One Int32 index grid per level; background -1 means "no corner".
class FeatureOctreeImpl {
  public:
    std::vector<openvdb::Int32Grid::Ptr> level_grids;
};

}  // namespace shine
