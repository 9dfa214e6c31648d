#include "vdbrad/scene/SurfacePlanes.h"

#include "vdbrad/core/VoxelMarch.h"
#include "vdbrad/scene/Emitters.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace vdbrad {

using openvdb::Coord;
using openvdb::Vec3d;

namespace {
// The neighbourhood: a cube of 2 kReach + 1 voxels. One voxel each way is not enough: a voxel at
// the edge of a 45-degree wall's band (3 voxels deep) sees only its own side of the band.
constexpr int kReach = 2;
// A wall's spread at its edge is about a voxel long: a third of one is a clear direction.
constexpr double kRuns = 0.3;
} // namespace

SurfacePlanes::SurfacePlanes(const Scene& scene)
    : mScene(&scene)
{
    const VoxelIndex& voxels = scene.voxels();
    // Emitters and the rest are different walls, however they face: a lamp a millimetre under
    // a ceiling (the Cornell mesh's) must not take the ceiling's plane, a voxel behind its own.
    mEmits.assign(scene.size(), 0);
    if (scene.hasEmission()) {
        for (size_t i = 0; i < scene.size(); ++i) {
            mEmits[i] = Emitters::emits(scene.emission().rgb(i));
        }
    }
    mOffset.assign(scene.size(), 0.f);
    mSpread.assign(scene.size(), openvdb::Vec3f(0.f));
    tbb::parallel_for(tbb::blocked_range<size_t>(0, voxels.leafCount()),
        [&](const tbb::blocked_range<size_t>& r) {
            VoxelIndex::Accessor acc(voxels.tree());
            for (size_t leaf = r.begin(); leaf != r.end(); ++leaf) {
                for (size_t i = voxels.leafBegin(leaf); i < voxels.leafBegin(leaf + 1); ++i) {
                    const Coord c = voxels.coord(i);
                    const openvdb::Vec3f& n = scene.normal(i);
                    Vec3d sum(0.0);   // of c_j - c over the wall's voxels around
                    int count = 1;    // the voxel itself, at 0
                    for (int dx = -kReach; dx <= kReach; ++dx) {
                        for (int dy = -kReach; dy <= kReach; ++dy) {
                            for (int dz = -kReach; dz <= kReach; ++dz) {
                                if (dx == 0 && dy == 0 && dz == 0) continue;
                                const int32_t j = acc.getValue(c.offsetBy(dx, dy, dz));
                                if (j < 0 || !sameWall(i, size_t(j))) continue;
                                sum += Vec3d(dx, dy, dz);
                                ++count;
                            }
                        }
                    }
                    const double half = 0.5 * (std::abs(n[0]) + std::abs(n[1]) + std::abs(n[2]));
                    const Vec3d mean = sum / double(count);
                    mOffset[i] = float(std::clamp(Vec3d(n).dot(mean), -half, half));
                    mSpread[i] = openvdb::Vec3f(mean);
                }
            }
        });
}

Vec3d
SurfacePlanes::point(size_t i) const
{
    return mScene->voxels().coord(i).asVec3d() + Vec3d(mScene->normal(i)) * double(mOffset[i]);
}

Vec3d
SurfacePlanes::rayOrigin(size_t i, const Vec3d& p, double lift) const
{
    const Vec3d n(mScene->normal(i));
    return p + n * ((point(i) - p).dot(n) + lift);
}

bool
SurfacePlanes::stops(size_t i, const Vec3d& o, const Vec3d& d, double tIn, double tOut,
    VoxelIndex::Accessor& acc) const
{
    const Vec3d n(mScene->normal(i));
    const Vec3d c = point(i);
    if (!crossesVoxelSurface(o, d, tIn, tOut, c, n)) return false;
    // Where the ray is first behind the plane: the entry, or the crossing.
    const double s0 = n.dot(o + d * tIn - c);
    if (s0 < 0.0 && n.dot(o + d * tOut - c) < 0.0 && openBehind(i, o + d * tIn, acc)) {
        return false;
    }
    const double t = s0 < 0.0 ? tIn : tIn + s0 / -n.dot(d);
    return !beyondConvexEdge(i, o + d * t, acc);
}

bool
SurfacePlanes::sameWall(size_t i, size_t j) const
{
    return mEmits[i] == mEmits[j] && mScene->normal(j).dot(mScene->normal(i)) >= kSameWall;
}

bool
SurfacePlanes::openBehind(size_t i, const Vec3d& entry, VoxelIndex::Accessor& acc) const
{
    // The faces of i's cube the entry point lies on (an edge or a corner: several). A ray that
    // starts inside the cube is not known to come from open space.
    constexpr double kOnFace = 1e-6;
    const Coord c = mScene->voxels().coord(i);
    bool onFace = false;
    for (int k = 0; k < 3; ++k) {
        const double f = entry[k] - double(c[k]);
        for (const int side : {-1, 1}) {
            if (side * f < 0.5 - kOnFace) continue;
            onFace = true;
            // The nine cubes beyond that face: a voxel of i's wall there makes it a crack.
            for (int a = -1; a <= 1; ++a) {
                for (int b = -1; b <= 1; ++b) {
                    Coord q = c;
                    q[k] += side;
                    q[(k + 1) % 3] += a;
                    q[(k + 2) % 3] += b;
                    const int32_t j = acc.getValue(q);
                    if (j >= 0 && sameWall(i, size_t(j))) return false;
                }
            }
        }
    }
    if (!onFace) return false;
    // A neighbour facing another way: i is on an edge of a body, whose inside is behind i's
    // plane (a ray entering there met the body). A coplanar wall of another kind (the ceiling
    // around a lamp) closes nothing.
    const openvdb::Vec3f& n = mScene->normal(i);
    for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
            for (int dz = -1; dz <= 1; ++dz) {
                const int32_t j = acc.getValue(c.offsetBy(dx, dy, dz));
                if (j >= 0 && mScene->normal(size_t(j)).dot(n) < kSameWall) return false;
            }
        }
    }
    return true;
}

bool
SurfacePlanes::beyondConvexEdge(size_t j, const Vec3d& x, VoxelIndex::Accessor& acc) const
{
    const Scene& scene = *mScene;
    const Coord cj = scene.voxels().coord(j);
    const Vec3d nj(scene.normal(j)), sj(mSpread[j]);
    for (int dx = -1; dx <= 1; ++dx) {
        for (int dy = -1; dy <= 1; ++dy) {
            for (int dz = -1; dz <= 1; ++dz) {
                const int32_t k = acc.getValue(cj.offsetBy(dx, dy, dz));
                if (k < 0 || size_t(k) == j) continue;
                const Vec3d nk(scene.normal(size_t(k)));
                // Another wall, and each runs behind the other's plane.
                if (nk.dot(nj) >= kSameWall || !(nk.dot(sj) < -kRuns)
                    || !(nj.dot(Vec3d(mSpread[size_t(k)])) < -kRuns)) {
                    continue;
                }
                if (nk.dot(x - point(size_t(k))) > 0.0) return true;
            }
        }
    }
    return false;
}

} // namespace vdbrad
