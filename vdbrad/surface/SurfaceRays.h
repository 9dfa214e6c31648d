// SurfaceRays: continuous rays against the voxelised surface, as the Monte Carlo reference and
// the renderer's final gather cast them.
//
// The voxelised surface: voxel v is its plane with normal n_v, clipped to its cube and to the
// convex edges of its wall (SurfacePlanes.h). A ray hits the first voxel whose surface it meets;
// v's front (d . n_v < 0) shows B(v), its back is black; leaving the scene's box is the sky.
// Rays leave a voxel from just in front of its plane (SurfacePlanes::rayOrigin: half a voxel for
// the gather, as for shadow rays; 0.01 for the Monte Carlo reference, whose estimate is the
// irradiance where rays start). Directions are cosine-distributed about a normal.
#pragma once

#include "vdbrad/core/SampleHash.h"
#include "vdbrad/core/VoxelMarch.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/scene/SurfacePlanes.h"

#include <openvdb/openvdb.h>

#include <cmath>
#include <cstdint>
#include <limits>

namespace vdbrad {

constexpr uint32_t kRaySky = 0xffffffffu;    ///< the ray leaves the scene
constexpr uint32_t kRayBack = 0xfffffffeu;   ///< the ray hits a voxel's back

/// What the ray @a origin + t @a d (index space, t > 0) from voxel @a self hits: a voxel index,
/// kRaySky or kRayBack. @a self's own cube never stops it.
inline uint32_t
traceSurface(const Scene& scene, const SurfacePlanes& planes, VoxelIndex::Accessor& acc,
    const openvdb::CoordBBox& box, uint32_t self, const openvdb::Vec3d& origin,
    const openvdb::Vec3d& d)
{
    using openvdb::Vec3d;
    uint32_t hit = kRaySky;
    // marchVoxels works in cells [c, c + 1): half a voxel off index space.
    marchVoxels(acc, box, origin + Vec3d(0.5), d, 0.0, std::numeric_limits<double>::infinity(),
        [&](int32_t index, double tIn, double tOut) {
            if (uint32_t(index) == self) return true;
            if (planes.stops(size_t(index), origin, d, tIn, tOut, acc)) {
                hit = d.dot(Vec3d(scene.normal(size_t(index)))) < 0.0 ? uint32_t(index) : kRayBack;
                return false;
            }
            return true;   // crosses the cube in front of the plane, or beyond an edge: passes
        });
    return hit;
}

/// S cosine-distributed directions about a unit normal: stratified in sin^2(theta) (equal-flux
/// bands of a cosine lobe), a golden-ratio sequence in phi, offsets from the hash @a h.
struct CosineRays
{
    CosineRays(const openvdb::Vec3f& normal, uint64_t h, size_t S)
        : n(normal), h(h), phase(unitHash(h)), S(double(S))
    {
        const openvdb::Vec3d axis = std::abs(n[0]) < 0.6 ? openvdb::Vec3d(1, 0, 0)
            : openvdb::Vec3d(0, 1, 0);
        t1 = n.cross(axis).unitSafe();
        t2 = n.cross(t1);
    }
    openvdb::Vec3d operator()(size_t s) const
    {
        const double u = (double(s) + unitHash(mixHash(h + 2 * s + 1))) / S;
        const double v = std::fmod(phase + 0.6180339887498949 * double(s), 1.0);
        const double sinT = std::sqrt(u), cosT = std::sqrt(1.0 - u);
        const double phi = 6.283185307179586 * v;   // 2 pi v
        return (t1 * (sinT * std::cos(phi)) + t2 * (sinT * std::sin(phi)) + n * cosT).unitSafe();
    }
    openvdb::Vec3d n, t1, t2;
    uint64_t h;
    double phase, S;
};

} // namespace vdbrad
