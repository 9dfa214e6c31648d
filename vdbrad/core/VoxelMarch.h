// VoxelMarch: the voxels of a VoxelIndex that a straight ray crosses, in order, with exact chord
// lengths: what the renderer (first hits, cloud emission-absorption), the solar beam (beam
// deposits) and the Monte Carlo solver (what a ray hits) all need.
#pragma once

#include "vdbrad/core/VoxelIndex.h"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace vdbrad {

// The cells of a voxel set along q(t) = q0 + t d, in order, for t in [tBegin, tEnd], in
// coordinates shifted by half a voxel so that the cube of voxel c is the cell [c, c + 1).
// visit(index, tIn, tOut) is called for every cell of the set the ray crosses (index >= 0 in
// the index tree) and returns false to stop. Empty space is crossed a node at a time: a cell in
// a tile or a missing child of the index tree (side 8, 128 or 4096) is left through that node's
// far face in one step -- the hierarchical DDA of OpenVDB's ray intersectors on the index tree's
// own levels. Cell boundaries are computed from q0 each time, never accumulated, so chord
// lengths are exact to rounding.
template<typename VisitT>
inline void
marchVoxels(VoxelIndex::Accessor& acc, const openvdb::CoordBBox& box, const openvdb::Vec3d& q0,
    const openvdb::Vec3d& d, double tBegin, double tEnd, VisitT&& visit)
{
    using openvdb::Coord;
    using openvdb::Vec3d;
    if (box.empty()) return;
    const Vec3d lo = box.min().asVec3d(), hi = (box.max() + Coord(1)).asVec3d();
    Vec3d inv;
    int step[3];
    for (int k = 0; k < 3; ++k) {
        step[k] = d[k] > 0.0 ? 1 : d[k] < 0.0 ? -1 : 0;
        if (step[k] == 0) {
            if (q0[k] < lo[k] || q0[k] >= hi[k]) return;
            inv[k] = std::numeric_limits<double>::infinity();
            continue;
        }
        inv[k] = 1.0 / d[k];
        double ta = (lo[k] - q0[k]) * inv[k], tb = (hi[k] - q0[k]) * inv[k];
        if (ta > tb) std::swap(ta, tb);
        tBegin = std::max(tBegin, ta);
        tEnd = std::min(tEnd, tb);
    }
    if (!(tBegin < tEnd)) return;

    Coord c;
    {
        const Vec3d q = q0 + d * tBegin;
        for (int k = 0; k < 3; ++k) {
            // The entry point lies on the box; a far-side face belongs to the last cell.
            c[k] = int32_t(std::clamp(std::floor(q[k]), lo[k], hi[k] - 1.0));
        }
    }
    double t = tBegin;
    while (t < tEnd) {
        const int32_t index = acc.getValue(c);
        const int64_t side = index >= 0 ? 1 : VoxelIndex::emptyNodeSide(acc, c);
        int64_t origin[3];
        double tOut = std::numeric_limits<double>::infinity();
        int axis = 0;
        for (int k = 0; k < 3; ++k) {
            origin[k] = int64_t(c[k]) & ~(side - 1);
            if (step[k] == 0) continue;
            const double face = double(step[k] > 0 ? origin[k] + side : origin[k]);
            const double tk = (face - q0[k]) * inv[k];
            if (tk < tOut) { tOut = tk; axis = k; }
        }
        tOut = std::max(tOut, t);   // a rounding-level step backwards is no step
        if (index >= 0 && !visit(index, t, std::min(tOut, tEnd))) return;
        if (tOut >= tEnd) return;
        if (side == 1) {
            c[axis] += step[axis];
        } else {
            // Across the exit face on the exit axis; where the ray is on the others (clamped to
            // the node we leave, against rounding at its edges).
            const Vec3d q = q0 + d * tOut;
            for (int k = 0; k < 3; ++k) {
                if (k == axis) {
                    c[k] = int32_t(step[k] > 0 ? origin[k] + side : origin[k] - 1);
                } else {
                    c[k] = int32_t(std::clamp(int64_t(std::floor(q[k])), origin[k],
                        origin[k] + side - 1));
                }
            }
        }
        t = tOut;
    }
}

/// Does the ray o + t d, crossing a cube for t in [tIn, tOut], cross the plane through @a c with
/// normal @a n there, or run behind it (it slipped through a crack between tilted patches)? One
/// that stays in front passes (a flat wall's neighbours, at grazing angles). The first test of
/// the surface rule (SurfacePlanes::stops), which puts @a c on the voxel's wall plane.
inline bool
crossesVoxelSurface(const openvdb::Vec3d& o, const openvdb::Vec3d& d, double tIn, double tOut,
    const openvdb::Vec3d& c, const openvdb::Vec3d& n)
{
    const double s0 = (o + d * tIn - c).dot(n), s1 = (o + d * tOut - c).dot(n);
    return std::min(s0, s1) < 0.0;
}

} // namespace vdbrad
