#include "vdbrad/cloud/SolarBeam.h"

#include "vdbrad/core/Constants.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/core/VoxelMarch.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>

namespace vdbrad {

namespace {

using openvdb::Coord;
using openvdb::Vec3d;

// Deposits are added up in fixed point (units of one ray's power, 2^-40 resolution): integer
// sums do not depend on the order threads add them in, so the result is the same bits for any
// thread count, and each ray's deposits plus what it keeps still add up to its power to 1e-12.
constexpr double kFixed = 1099511627776.0;   // 2^40

struct Marcher
{
    const std::vector<float>& depth;
    std::vector<std::atomic<int64_t>>& deposited;
    openvdb::CoordBBox box;   // the medium's bounding box (index)
    int up;
    bool periodic;
    const GroundLayer* ground;
    std::vector<std::atomic<int64_t>>& landed;   // per ground cell
    const std::vector<uint8_t>* opaque;          // per voxel, or null

    // What is left of a ray that leaves the medium along d at point q (cell space), on the
    // ground cell under it (an open box's ray that leaves through a side meets the ground's
    // plane outside the footprint).
    void land(const Vec3d& q, const Vec3d& d, int64_t left) const
    {
        if (!ground || left <= 0) return;
        const int64_t cell = ground->cellBelow(q - Vec3d(0.5), d, periodic);
        if (cell >= 0) landed[size_t(cell)].fetch_add(left, std::memory_order_relaxed);
    }

    // March the ray o + t d (index space, unit d) from t0 to t1, or, periodic, across the
    // horizontal copies of the box until it leaves through the bottom; deposit what each voxel
    // takes (and, with a ground, what is left where the ray reaches it) and return what is
    // left of the ray's power (fixed point).
    int64_t march(const Vec3d& o, const Vec3d& d, double t0, double t1,
        VoxelIndex::Accessor& acc) const
    {
        int64_t left = int64_t(kFixed);
        double kept = 1.0;   // transmittance so far, in double; deposits are its decrements
        auto take = [&](int32_t i, double tIn, double tOut) {
            if (opaque && (*opaque)[size_t(i)]) {   // a surface: what is left lands on it
                deposited[size_t(i)].fetch_add(left, std::memory_order_relaxed);
                left = 0;
                return false;
            }
            const double after = kept * std::exp(-double(depth[size_t(i)]) * (tOut - tIn));
            // Fixed-point share of this voxel; a ray whose power is spent deposits the rest
            // here, so nothing is lost to rounding or underflow.
            int64_t share = int64_t(std::llround((kept - after) * kFixed));
            if (after * kFixed < 1.0 || share > left) share = left;
            if (share > 0) {
                deposited[size_t(i)].fetch_add(share, std::memory_order_relaxed);
                left -= share;
            }
            kept = after;
            return left > 0;
        };
        // marchVoxels works in cells [c, c + 1): half a voxel off index space.
        Vec3d q = o + Vec3d(0.5);
        if (!periodic) {
            marchVoxels(acc, box, q, d, t0, t1, take);
            land(q, d, left);
            return left;
        }
        // One copy of the box at a time: where the ray leaves through a side, the origin moves
        // back by one period, so the same t goes on in the copy it enters.
        const Vec3d lo = box.min().asVec3d(), hi = (box.max() + openvdb::Coord(1)).asVec3d();
        double t = t0;
        while (left > 0) {
            double tExit = std::numeric_limits<double>::infinity();
            int axis = up;
            for (int k = 0; k < 3; ++k) {
                if (d[k] == 0.0) continue;
                const double tk = ((d[k] > 0.0 ? hi[k] : lo[k]) - q[k]) / d[k];
                if (tk < tExit) { tExit = tk; axis = k; }
            }
            marchVoxels(acc, box, q, d, t, tExit, take);
            if (axis == up) {   // out through the bottom: the rest is transmitted
                land(q, d, left);
                break;
            }
            q[axis] -= (d[axis] > 0.0 ? 1.0 : -1.0) * (hi[axis] - lo[axis]);
            t = tExit;
        }
        return left;
    }
};

// The grid of parallel rays: ray (row, col) starts at origin + col e1 + row e2 and stands for a
// patch of the beam's cross-section of area `area` (voxel faces).
struct RayGrid
{
    Vec3d origin, e1, e2;
    int rows = 0, cols = 0;
    double area = 0.0;
};

// Throws for invalid arguments (traceSolarBeam()'s), the first one found in the order below;
// returns |toSun|.
double
checkArguments(const VoxelIndex& voxels, const std::vector<float>& opticalDepth,
    const Vec3d& toSun, int up, int raysPerVoxel, double irradiance, const GroundLayer* ground)
{
    if (up < 0 || up > 2) OPENVDB_THROW(openvdb::ValueError, "up axis must be 0, 1 or 2");
    if (opticalDepth.size() != voxels.size()) {
        OPENVDB_THROW(openvdb::ValueError, "one optical depth per voxel expected");
    }
    if (raysPerVoxel < 1 || raysPerVoxel > 64) {
        OPENVDB_THROW(openvdb::ValueError, "rays per voxel must be in [1, 64]");
    }
    if (!(irradiance >= 0.0) || !std::isfinite(irradiance)) {
        OPENVDB_THROW(openvdb::ValueError, "irradiance must be finite and >= 0");
    }
    if (ground && ground->up() != up) {
        OPENVDB_THROW(openvdb::ValueError, "the ground's vertical axis is not the beam's");
    }
    const double len = toSun.length();
    if (!(len > 0.0) || !std::isfinite(len) || !(toSun[up] / len > 1e-3)) {
        OPENVDB_THROW(openvdb::ValueError, "the sun must be above the horizon (elevation > 0.06 "
            "degrees)");
    }
    return len;
}

// Rays on the plane of the box [lo, hi]'s top face, @a spacing apart along the horizontal axes:
// over one period (periodic), or over the footprint and upstream of it as far as rays along
// @a d still reach the sunlit sides (an open box over a ground).
RayGrid
topFaceGrid(const Vec3d& lo, const Vec3d& hi, const Vec3d& d, int up, bool periodic,
    int raysPerVoxel, double spacing)
{
    RayGrid grid;
    const int h1 = (up + 1) % 3, h2 = (up + 2) % 3;
    grid.e1 = Vec3d(0.0); grid.e1[h1] = spacing;
    grid.e2 = Vec3d(0.0); grid.e2[h2] = spacing;
    grid.origin = lo;
    grid.origin[up] = hi[up];
    Vec3d end = hi;
    if (!periodic) {
        // A ray through the bottom of a sunlit side started this far upstream.
        const double reach = (hi[up] - lo[up]) / std::abs(d[up]);
        for (const int k : {h1, h2}) {
            const double shift = -d[k] * reach;
            const double steps = std::ceil(std::abs(shift) / spacing - 1e-9);
            if (shift < 0.0) grid.origin[k] -= steps * spacing;
            else end[k] += steps * spacing;
        }
    }
    grid.cols = int(std::lround((end[h1] - grid.origin[h1]) * raysPerVoxel));
    grid.rows = int(std::lround((end[h2] - grid.origin[h2]) * raysPerVoxel));
    grid.origin += 0.5 * (grid.e1 + grid.e2);
    grid.area = spacing * spacing * std::abs(d[up]);
    return grid;
}

// Rays on the plane normal to the beam @a d, @a spacing apart, over the shadow of the box
// [lo, hi], starting well outside the box, upstream.
RayGrid
crossSectionGrid(const Vec3d& lo, const Vec3d& hi, const Vec3d& d, int raysPerVoxel,
    double spacing)
{
    RayGrid grid;
    // Orthonormal axes of the cross-section, and the shadow's extent along them.
    const Vec3d a = std::abs(d[0]) < 0.9 ? Vec3d(1, 0, 0) : Vec3d(0, 1, 0);
    const Vec3d u = d.cross(a).unit(), v = d.cross(u);
    double u0 = 1e300, u1 = -1e300, v0 = 1e300, v1 = -1e300;
    const Vec3d centre = 0.5 * (lo + hi);
    for (int c = 0; c < 8; ++c) {
        const Vec3d corner(c & 1 ? hi[0] : lo[0], c & 2 ? hi[1] : lo[1], c & 4 ? hi[2] : lo[2]);
        const Vec3d r = corner - centre;
        u0 = std::min(u0, r.dot(u)); u1 = std::max(u1, r.dot(u));
        v0 = std::min(v0, r.dot(v)); v1 = std::max(v1, r.dot(v));
    }
    grid.cols = int(std::ceil((u1 - u0) * raysPerVoxel));
    grid.rows = int(std::ceil((v1 - v0) * raysPerVoxel));
    grid.e1 = u * spacing;
    grid.e2 = v * spacing;
    // Start well outside the box, upstream.
    grid.origin = centre + u * u0 + v * v0 - d * ((hi - lo).length() + 1.0)
        + 0.5 * (grid.e1 + grid.e2);
    grid.area = spacing * spacing;
    return grid;
}

// Slab test of the ray o + t d against the box [lo, hi]: narrows [t0, t1] to the part inside,
// false if it misses.
inline bool
clipToBox(const Vec3d& o, const Vec3d& d, const Vec3d& lo, const Vec3d& hi, double& t0,
    double& t1)
{
    bool hit = true;
    for (int k = 0; k < 3 && hit; ++k) {
        if (d[k] == 0.0) {
            hit = o[k] >= lo[k] && o[k] <= hi[k];
            continue;
        }
        double a = (lo[k] - o[k]) / d[k], b = (hi[k] - o[k]) / d[k];
        if (a > b) std::swap(a, b);
        t0 = std::max(t0, a);
        t1 = std::min(t1, b);
        hit = t0 < t1;
    }
    return hit;
}

} // namespace

SolarBeamResult
traceSolarBeam(const VoxelIndex& voxels, const std::vector<float>& opticalDepth,
    const Vec3d& toSun, int up, bool periodic, int raysPerVoxel, double irradiance,
    openvdb::util::NullInterrupter* interrupt, const GroundLayer* ground,
    const std::vector<uint8_t>* opaque)
{
    const double len = checkArguments(voxels, opticalDepth, toSun, up, raysPerVoxel, irradiance,
        ground);
    SolarBeamResult result;
    const size_t n = voxels.size();
    if (n == 0) return result;
    const Vec3d d = -toSun / len;   // propagation
    // The medium's box: above the ground's layer, if the voxels hold it.
    openvdb::CoordBBox box = voxels.bbox();
    if (ground && box.min()[up] <= ground->layer()) box.min()[up] = ground->layer() + 1;
    const Vec3d lo = box.min().asVec3d() - Vec3d(0.5), hi = box.max().asVec3d() + Vec3d(0.5);
    std::vector<std::atomic<int64_t>> deposited(n), landed(ground ? ground->size() : 0);
    const Marcher marcher{opticalDepth, deposited, box, up, periodic, ground, landed, opaque};
    const double spacing = 1.0 / raysPerVoxel;

    // The ray grid: on the top face (periodic), or on the plane normal to the beam over the
    // box's shadow (open). An open box over a ground launches its rays from the plane of the
    // top face too: the rays then meet the ground on a lattice as regular as the top face's, the
    // same number per cell (from the plane normal to the beam their spacing on the ground is
    // stretched by 1 / cos(zenith): stripes in the ground's irradiance).
    const RayGrid grid = periodic || ground
        ? topFaceGrid(lo, hi, d, up, periodic, raysPerVoxel, spacing)
        : crossSectionGrid(lo, hi, d, raysPerVoxel, spacing);

    std::atomic<int64_t> enteredRays{0}, keptFixed{0};
    std::atomic<bool> cancelled{false};
    tbb::parallel_for(tbb::blocked_range<int>(0, grid.rows),
        [&](const tbb::blocked_range<int>& r) {
        if (cancelled || openvdb::util::wasInterrupted(interrupt)) { cancelled = true; return; }
        VoxelIndex::Accessor acc(voxels.tree());
        int64_t entered = 0, kept = 0;
        for (int row = r.begin(); row != r.end(); ++row) {
            for (int col = 0; col < grid.cols; ++col) {
                const Vec3d o = grid.origin + grid.e1 * double(col) + grid.e2 * double(row);
                double t0 = 0.0, t1 = 1e300;
                if (!periodic && !clipToBox(o, d, lo, hi, t0, t1)) continue;
                ++entered;
                kept += marcher.march(o, d, t0, t1, acc);
            }
        }
        enteredRays += entered;
        keptFixed += kept;
    });
    if (cancelled) throw Cancelled("solar beam");

    const double rayPower = irradiance * grid.area;
    result.deposited.resize(n);
    for (size_t i = 0; i < n; ++i) {
        result.deposited[i] = double(deposited[i].load()) / kFixed * rayPower;
    }
    result.incident = double(enteredRays.load()) * rayPower;
    result.transmitted = double(keptFixed.load()) / kFixed * rayPower;
    result.ground.resize(landed.size());
    for (size_t c = 0; c < landed.size(); ++c) {
        result.ground[c] = double(landed[c].load()) / kFixed * rayPower;
    }
    return result;
}

} // namespace vdbrad
