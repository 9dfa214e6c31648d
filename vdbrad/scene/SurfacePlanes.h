// SurfacePlanes: where in its cube each surface voxel's surface lies, and the rule by which a
// ray meets it (shadow rays of the direct light, the Monte Carlo reference, the renderer's
// final gather).
//
// A surface voxel knows its normal, not where its surface crosses its cube. Through the centre
// (VoxelMarch.h, crossesVoxelSurface) a tilted flat wall's planes form a staircase up to
// ||n||_1 voxels deep: every centre plane stands in front of some neighbours' and a ray leaving
// along the wall is stopped by the wall itself (vertical stripes, up to 9 % dark, on the Cornell
// box's rotated tall block at res 128; the Monte Carlo reference's blocks 30-50 % dark). Here
// the plane goes through the mean of n . c over the voxel and those of its neighbours within
// kReach that face the same way: the wall's own plane, to a fraction of a voxel, and the same
// plane for all of them. Flat axis walls one voxel thick keep the centre plane (offset 0); a wall
// two voxels thick gets one plane between its layers.
//
// At a block's convex edge each face's voxels overhang the other face by up to ||n||_1, and so
// do their planes; the real surface stops at the edge, behind the other face's plane. So a point
// of a voxel's plane in front of the plane of a neighbour of another wall is off the surface when
// the two walls make a convex edge: each runs away behind the other's plane (the same
// neighbourhood says which way a wall runs from each voxel: spread()). A block standing on a
// floor makes a concave edge (its face runs up, in front of the floor's plane): nothing is cut.
// Without the cut the tall block lost up to 18 % of its direct light over its top ten rows to
// its top face's overhang (docs/journal/2026-12-03-exact-direct-light.md).
#pragma once

#include "vdbrad/core/VoxelIndex.h"
#include "vdbrad/scene/Scene.h"

#include <openvdb/openvdb.h>

#include <vector>

namespace vdbrad {

/// Neighbours whose unit normals have at least this dot product with a voxel's count as the same
/// wall (18 degrees: a sphere of radius 3 voxels still averages its neighbours; the faces of a
/// box, at 90 degrees, never do).
constexpr float kSameWall = 0.95f;

/// Rays leave a voxel this far (voxels) in front of its plane, where no voxel of its own wall
/// stands: from the plane itself rounding decides whether a ray grazing a flat wall is stopped.
constexpr double kRayLift = 0.5;

class SurfacePlanes
{
public:
    SurfacePlanes() = default;
    /// The planes of @a scene's voxels (kept by pointer: the scene must outlive this).
    explicit SurfacePlanes(const Scene& scene);

    /// Voxel @a i's surface is the plane n . (x - c) = offset(i) (index units), with
    /// |offset| <= ||n||_1 / 2 so that it crosses the cube.
    float offset(size_t i) const { return mOffset[i]; }
    /// The mean of c_j - c over the voxel and its wall's voxels around it: which way its wall
    /// extends from it (about 0 inside a wall, about a voxel long away from a wall's edge).
    const openvdb::Vec3f& spread(size_t i) const { return mSpread[i]; }
    /// A point of voxel @a i's plane (index space).
    openvdb::Vec3d point(size_t i) const;
    /// Where a ray from voxel @a i starts when it leaves from index-space point @a p of its
    /// plane (or of the centre plane: p is moved onto this one): @a lift in front of it.
    openvdb::Vec3d rayOrigin(size_t i, const openvdb::Vec3d& p, double lift = kRayLift) const;

    /// @brief Does the ray o + t d (index space), crossing voxel @a i's cube for t in
    /// [@a tIn, @a tOut], meet the voxel's surface? It does if it crosses the plane there or
    /// runs behind it having come through a face of the cube that borders its wall (it slipped
    /// through a crack between tilted patches), unless that point is beyond a convex edge of
    /// the voxel's wall. One that stays in front passes (a flat wall's neighbours, at grazing
    /// angles), and so does one that enters behind the plane from beyond a free edge of a sheet
    /// (no voxel of the wall across the face it entered by, none facing another way around)
    /// and stays behind it: the open side of a lamp hung under a ceiling, or under a lone
    /// plate, did not meet it (the mesh's thin quad). @a acc: any accessor of the index tree.
    bool stops(size_t i, const openvdb::Vec3d& o, const openvdb::Vec3d& d, double tIn,
        double tOut, VoxelIndex::Accessor& acc) const;

private:
    bool beyondConvexEdge(size_t j, const openvdb::Vec3d& x, VoxelIndex::Accessor& acc) const;
    bool sameWall(size_t i, size_t j) const;
    bool openBehind(size_t i, const openvdb::Vec3d& entry, VoxelIndex::Accessor& acc) const;

    const Scene* mScene = nullptr;
    std::vector<float> mOffset;
    std::vector<openvdb::Vec3f> mSpread;
    std::vector<char> mEmits;   // per voxel: emits (Emitters::emits); a wall never mixes them
};

} // namespace vdbrad
