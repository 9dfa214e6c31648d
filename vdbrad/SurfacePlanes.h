// SurfacePlanes: where in its cube each surface voxel's surface lies.
//
// A surface voxel knows its normal, not where its surface crosses its cube; the rule that stops
// rays (VoxelMarch.h, crossesVoxelSurface) puts the plane through the centre. On a tilted flat
// wall the centres form a staircase up to ||n||_1 voxels deep, so every centre plane stands in
// front of some neighbours' and a shadow ray leaving along the wall is stopped by the wall
// itself: vertical stripes, up to 9 % dark, on the Cornell box's rotated tall block at res 128
// (BENCHMARKS.md, "Exact direct light"). The mean of n . c over the voxel and those of its 26
// neighbours that face the same way is the wall's own plane, to a fraction of a voxel, and the
// same plane for all of them: a wall no longer shadows itself. Flat axis walls one voxel thick
// keep the centre plane (offset 0); a wall two voxels thick gets one plane between its layers.
// The same neighbourhood says which way a wall extends from each voxel, which shadow rays need at
// convex edges (DirectLight.cc).
#pragma once

#include "vdbrad/Scene.h"

#include <vector>

namespace vdbrad {

/// Neighbours whose unit normals have at least this dot product with a voxel's count as the same
/// wall (18 degrees: a sphere of radius 3 voxels still averages its neighbours; the faces of a
/// box, at 90 degrees, never do).
constexpr float kSameWall = 0.95f;

struct SurfacePlanes
{
    /// Per voxel (index units): the voxel's surface is the plane n . (x - c) = offset, with
    /// |offset| <= ||n||_1 / 2 so that it crosses the cube.
    std::vector<float> offset;
    /// Per voxel: the mean of c_j - c over the voxel and its wall's voxels around it (index
    /// units), which way its wall extends from it. About 0 inside a wall; at a wall's edge it
    /// points away from the edge, about a voxel long. It tells a block's convex edges (each
    /// wall runs behind the other's plane) from a concave one (a block standing on a floor:
    /// the block's face runs up, in front of the floor's plane).
    std::vector<openvdb::Vec3f> spread;
};

/// @brief The planes of @a scene's voxels and which way their walls extend.
SurfacePlanes surfacePlanes(const Scene& scene);

} // namespace vdbrad
