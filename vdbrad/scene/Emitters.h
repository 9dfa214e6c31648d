// Emitters: a scene's emitting voxels as planar patches whose outlines give exact form factors.
//
// Direct light from a small source is what a fixed direction set renders worst (a receiver sees
// it through a handful of directions: stripes). DirectLight.h integrates it exactly instead, and
// for that the emitting voxels need a surface with an outline: connected emitting voxels (26-
// neighbours) of one emission value and one normal (within 1e-4) form a patch. A patch is the
// plane of its normal through the mean of its centres, over the columns its voxels occupy along
// the normal's dominant axis k: each column (i, j) of the two other axes carries the unit square
// [i - 1/2, i + 1/2] x [j - 1/2, j + 1/2] lifted onto the plane (area 1 / |n_k|). The squares of a
// digital plane tile the real plane exactly (naive planes have one voxel per column; a thicker,
// 26-separating one is counted once per column), so an axis-aligned light quad of k x l voxels is
// exactly a k x l rectangle, whatever its offset in the grid.
//
// Power: exitance times area. With an `emission_area` grid (the voxelizer's: the mesh's emitting
// area inside each voxel) a patch's exitance is scaled so that its power is the mesh's,
// whatever the voxels' coverage of the light's rim.
//
// Outline: the squares' edges, an edge shared by two squares cancelled, traced into closed loops
// (holes run the other way) and collinear edges merged, so a rectangle has four edges however
// many voxels it covers. Lambert's contour formula over these loops is the exact form factor of
// the patch (DirectLight.h), at a cost proportional to its outline, not its area.
#pragma once

#include "vdbrad/scene/Scene.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <vector>

namespace vdbrad {

struct EmitterPatch
{
    openvdb::Vec3d normal;                 // unit, index space, towards the lit side
    int axis = 2;                          // the normal's dominant axis
    double offset = 0.0;                   // the plane: normal . q = offset
    openvdb::Vec3d exitance;               // emitted radiosity per channel (grey: all equal)
    std::vector<openvdb::Vec2i> columns;   // (i, j) on the axes other than `axis`, sorted
    openvdb::Vec2i lower, upper;           // the columns' bounding rectangle (inclusive)
    /// Closed boundary loops on the plane (index space), collinear edges merged.
    std::vector<std::vector<openvdb::Vec3d>> loops;
    double area = 0.0;                     // columns / |normal[axis]|, in voxel faces
    openvdb::Vec3d centre;                 // of the bounding sphere of the outline
    double radius = 0.0;

    /// The point of the plane over (u, v) on the two other axes (in increasing axis order).
    openvdb::Vec3d lift(double u, double v) const;
    /// True if the point (u, v) on the two other axes lies in one of the patch's columns.
    bool covers(double u, double v) const;
    /// Emitted power per channel (exitance times area, index-space area).
    openvdb::Vec3d power() const { return exitance * area; }
};

class Emitters
{
public:
    static constexpr int32_t kNone = -1;

    Emitters() = default;
    /// True if an emission value emits (any channel > 0): the one rule for "emitting voxel".
    static bool emits(const openvdb::Vec3f& e) { return e[0] > 0.f || e[1] > 0.f || e[2] > 0.f; }

    /// Group the emitting voxels of @a scene (emits()) into patches.
    explicit Emitters(const Scene& scene);

    const std::vector<EmitterPatch>& patches() const { return mPatches; }
    bool empty() const { return mPatches.empty(); }
    /// The patch voxel @a i emits as part of, or kNone.
    int32_t patchOf(size_t i) const { return mPatchOf.empty() ? kNone : mPatchOf[i]; }
    /// Number of emitting voxels.
    size_t voxels() const { return mVoxels; }
    /// Total emitted power (channel mean), index-space area.
    double power() const;
    /// Edges of all outlines: what a receiver's exact form factors cost.
    size_t edges() const;
    /// Each voxel's emitted radiosity as its patch emits it: @a scene's emission, scaled to
    /// the mesh's power where the scene has an `emission_area` grid (otherwise a copy of the
    /// emission). What a method that meets the emitting voxels themselves (Monte Carlo rays)
    /// must use to agree with the exact direct light. @a scene is the one given to the
    /// constructor.
    Attribute exitance(const Scene& scene) const;

private:
    std::vector<EmitterPatch> mPatches;
    std::vector<int32_t> mPatchOf;
    size_t mVoxels = 0;
};

} // namespace vdbrad
