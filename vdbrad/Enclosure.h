// Enclosure: which air region each surface voxel faces: the open outside or a closed cavity.
//
// Digital lines start at voxel centres, and a voxel at an edge or corner of a closed room (or on
// the outer fringe of a digitised curved wall) has directions in its hemisphere that leave
// through the wall itself. Two things go wrong with them, and the region each voxel faces fixes
// both:
//   - light leaks: such a ray reaches voxels outside the room. Light is only exchanged between
//     voxels that face the same region (LineSweep);
//   - energy is lost in closed rooms: such a ray meets nothing, although no sky exists in a
//     closed room (a closed furnace then converges below E / (1 - rho)). A voxel facing a closed
//     cavity cannot see the sky, so the solver renormalises its weights over the directions that
//     do meet a voxel. Voxels facing the outside keep their losses: those are the sky.
//
// Regions come from flood-filling the empty cells of the bounding box (grown by one cell) with the
// connectivity light has on the lines (26 for naive, 6 for standard lines): the fill from the
// border is the outside (region 0); every cavity it cannot reach gets its own number. A voxel
// faces the region of the first empty cell met stepping from it along its normal.
#pragma once

#include "vdbrad/LinePartition.h"
#include "vdbrad/VoxelIndex.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <vector>

namespace vdbrad {

struct Regions
{
    /// Per voxel: 0 = faces the outside, k >= 1 = faces closed cavity k.
    std::vector<uint32_t> region;
    uint32_t cavities = 0;      ///< number of closed cavities
    bool analysed = false;      ///< false if the box was too large: everything is then region 0
};

/// @brief The region every voxel of @a voxels faces (see the file comment).
/// @param maxCells  bounding boxes with more cells than this are not analysed (every voxel is then
///                  region 0: no renormalisation, and only the line rules stop light at walls);
///                  the fill needs one bit per cell
Regions findRegions(const VoxelIndex& voxels, const std::vector<openvdb::Vec3f>& normals,
    LineType lines, uint64_t maxCells = uint64_t(1) << 31);

} // namespace vdbrad
