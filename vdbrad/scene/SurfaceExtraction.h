// SurfaceExtraction: the surface voxels of a level set, and their normals.
//
// A surface voxel is an active voxel on the inside (phi <= 0) with a neighbour outside (phi > 0):
// the inner boundary of the solid. Which neighbours count decides what the surface blocks
// (thesis ch. 3): with the 6 face neighbours the boundary is 6-separating (it stops 6-connected,
// "standard" lines); with all 26 neighbours it is 26-separating (it also stops 26-connected,
// "naive" lines, at the price of a slightly thicker shell). The default, 26, is safe for both
// line types. Normals are the normalised central-difference gradient of phi, in index space.
#pragma once

#include "vdbrad/core/VoxelIndex.h"

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <vector>

namespace vdbrad {

/// @brief Mask of the surface voxels of @a levelSet (see file comment).
/// @param separation  6 or 26
/// @throw openvdb::ValueError if a value is NaN/infinite or @a separation is not 6 or 26
/// @throw vdbrad::Cancelled if @a interrupt asks to stop
openvdb::MaskTree::Ptr extractSurfaceVoxels(const openvdb::FloatGrid& levelSet, int separation = 26,
    openvdb::util::NullInterrupter* interrupt = nullptr);

/// @brief Index-space unit outward normals of @a levelSet at the voxels of @a index.
/// Where the central-difference gradient vanishes (a one-voxel-thin sheet, where both sides cancel)
/// the normal falls back to the mean direction of the outside neighbours.
std::vector<openvdb::Vec3f> levelSetNormals(const openvdb::FloatGrid& levelSet,
    const VoxelIndex& index);

} // namespace vdbrad
