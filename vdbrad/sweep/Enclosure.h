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
// Regions are the connected components of the empty cells (not surface voxels) with the
// connectivity light has on the lines (26 for naive, 6 for standard lines): the component that
// reaches infinity is the outside (region 0); every other one is a closed cavity, numbered in the
// order the voxels (in index order) first face it. A voxel faces the region of the first empty
// cell met stepping from it along its normal, at most 3 steps and within the bounding box grown
// by one cell.
//
// The components are found on OpenVDB's 8^3 leaf grid, so the work and memory follow the surface,
// not the volume: a block holding no surface voxel is one node, a leaf of the index is split into
// its own components (bit masks of 512 cells), and a union-find joins nodes that touch across
// block faces, edges and corners.
#pragma once

#include "vdbrad/core/VoxelIndex.h"
#include "vdbrad/sweep/LinePartition.h"

#include <openvdb/openvdb.h>

#include <cstddef>
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
/// @param maxBlocks  scenes spanning more 8^3 blocks than this (regionBlocks()) are not analysed
///                   (every voxel is then region 0: no renormalisation, and only the line rules
///                   stop light at walls); the fill needs 4 bytes per block (regionsBytes())
Regions findRegions(const VoxelIndex& voxels, const std::vector<openvdb::Vec3f>& normals,
    LineType lines, uint64_t maxBlocks = uint64_t(1) << 26);

/// @brief The 8^3 blocks findRegions() spans for @a voxels: those of the bounding box grown by one
/// block on every side (0 for an empty set). What its @a maxBlocks caps.
uint64_t regionBlocks(const VoxelIndex& voxels);

/// @brief Bytes findRegions() holds while it runs on @a voxels, besides its result: 4 per block,
/// 4 per voxel and ~150 per leaf (two components of a wall leaf; each further one costs 68).
size_t regionsBytes(const VoxelIndex& voxels);

} // namespace vdbrad
