#include "vdbrad/mesh/MeshTracer.h"

#include "vdbrad/core/VoxelMarch.h"
#include "vdbrad/mesh/Voxelizer.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <utility>

namespace vdbrad {

using openvdb::Coord;
using openvdb::Vec3d;

namespace {

// More (cell, triangle) pairs than this are refused before they are made: 2^30 pairs are 16 GiB
// while binning.
constexpr uint64_t kMaxPairs = uint64_t(1) << 30;

} // namespace

MeshTracer::MeshTracer(const TriangleMesh& mesh, double cellSize)
    : mCell(cellSize)
{
    if (!(cellSize > 0.0) || !std::isfinite(cellSize)) {
        OPENVDB_THROW(openvdb::ValueError, "mesh cell size must be positive, got " << cellSize);
    }
    for (const openvdb::Vec3f& p : mesh.points) {
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
            OPENVDB_THROW(openvdb::ValueError, "mesh has a NaN or infinite point " << p);
        }
    }
    const double inv = 1.0 / cellSize;
    uint64_t bound = 0;   // cells of the triangles' boxes: at least the pairs binning makes
    for (size_t i = 0; i < mesh.triangles.size(); ++i) {
        const openvdb::Vec3I& t = mesh.triangles[i];
        const Vec3d a(mesh.points[t[0]]), b(mesh.points[t[1]]), c(mesh.points[t[2]]);
        if (!((b - a).cross(c - a).lengthSqr() > 0.0)) continue;
        mTriangles.push_back(Triangle{a, b - a, c - a, uint32_t(i)});
        uint64_t cells = 1;
        for (int k = 0; k < 3; ++k) {
            const double lo = std::min({a[k], b[k], c[k]}) * inv;
            const double hi = std::max({a[k], b[k], c[k]}) * inv;
            cells *= uint64_t(std::floor(hi) - std::floor(lo)) + 1;
        }
        mBounds.expand(a);
        mBounds.expand(b);
        mBounds.expand(c);
        bound += cells;
        if (bound > kMaxPairs) {
            OPENVDB_THROW(openvdb::ValueError, "mesh too large for cells of " << cellSize
                << " world units (more than " << kMaxPairs << " cell-triangle pairs)");
        }
    }

    // Each triangle's cells, exactly (cell c is the cube [c, c + 1) in units of the cell edge).
    using Pairs = std::vector<std::pair<Coord, uint32_t>>;
    tbb::enumerable_thread_specific<Pairs> perThread;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, mTriangles.size()),
        [&](const tbb::blocked_range<size_t>& r) {
            Pairs& pairs = perThread.local();
            for (size_t i = r.begin(); i != r.end(); ++i) {
                const Triangle& tri = mTriangles[i];
                const Vec3d a = tri.a * inv, b = (tri.a + tri.ab) * inv, c = (tri.a + tri.ac) * inv;
                Coord lo, hi;
                for (int k = 0; k < 3; ++k) {
                    lo[k] = int32_t(std::floor(std::min({a[k], b[k], c[k]})));
                    hi[k] = int32_t(std::floor(std::max({a[k], b[k], c[k]})));
                }
                for (Coord q = lo; q[0] <= hi[0]; ++q[0]) {
                    for (q[1] = lo[1]; q[1] <= hi[1]; ++q[1]) {
                        for (q[2] = lo[2]; q[2] <= hi[2]; ++q[2]) {
                            if (triangleMeetsVoxel(q.asVec3d() + Vec3d(0.5), a, b, c)) {
                                pairs.emplace_back(q, uint32_t(i));
                            }
                        }
                    }
                }
            }
        });
    openvdb::MaskTree mask;
    for (const Pairs& pairs : perThread) {
        for (const auto& p : pairs) mask.setValueOn(p.first);
    }
    mCells = VoxelIndex(mask);
    mCellBox = mCells.bbox();
    mBegin.assign(mCells.size() + 1, 0);
    for (const Pairs& pairs : perThread) {
        for (const auto& p : pairs) ++mBegin[size_t(mCells.find(p.first)) + 1];
    }
    for (size_t i = 0; i < mCells.size(); ++i) mBegin[i + 1] += mBegin[i];
    mList.resize(mBegin.back());
    std::vector<uint32_t> fill(mBegin.begin(), mBegin.end() - 1);
    for (const Pairs& pairs : perThread) {
        for (const auto& p : pairs) mList[fill[size_t(mCells.find(p.first))]++] = p.second;
    }
    // Threads binned in any order; the same lists every time keep ties between triangles (a ray
    // through a shared edge) deterministic.
    for (size_t i = 0; i < mCells.size(); ++i) {
        std::sort(mList.begin() + mBegin[i], mList.begin() + mBegin[i + 1]);
    }
}

bool
MeshTracer::intersect(const Vec3d& eye, const Vec3d& dir, double t0, double t1, Hit& hit,
    Accessor& acc) const
{
    double best = t1;
    int64_t found = -1;
    const double inv = 1.0 / mCell;
    marchVoxels(acc, mCellBox, eye * inv, dir * inv, t0, t1,
        [&](int32_t cell, double, double tOut) {
            for (uint32_t k = mBegin[size_t(cell)]; k < mBegin[size_t(cell) + 1]; ++k) {
                // Moller-Trumbore, closed triangle, either side.
                const Triangle& tri = mTriangles[mList[k]];
                const Vec3d p = dir.cross(tri.ac);
                const double det = tri.ab.dot(p);
                if (det == 0.0) continue;   // the ray runs in the triangle's plane
                const double id = 1.0 / det;
                const Vec3d s = eye - tri.a;
                const double u = s.dot(p) * id;
                if (!(u >= 0.0 && u <= 1.0)) continue;
                const Vec3d q = s.cross(tri.ab);
                const double v = dir.dot(q) * id;
                if (!(v >= 0.0 && u + v <= 1.0)) continue;
                const double t = tri.ac.dot(q) * id;
                if (t >= t0 && t <= best) {
                    // Equal distances (a shared edge): the lower triangle index, as sorted.
                    if (t == best && found >= 0) continue;
                    best = t;
                    found = int64_t(mList[k]);
                }
            }
            // A hit beyond this cell may still be beaten by one in the next cells.
            return !(found >= 0 && best <= tOut);
        });
    if (found < 0) return false;
    const Triangle& tri = mTriangles[size_t(found)];
    Vec3d n = tri.ab.cross(tri.ac).unit();
    if (n.dot(dir) > 0.0) n = -n;
    hit.t = best;
    hit.normal = n;
    hit.triangle = tri.id;
    return true;
}

} // namespace vdbrad
