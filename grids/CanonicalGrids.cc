// Canonical scenes and clouds: see CanonicalGrids.h for each scene's geometry and exact answer.
//
// Units: world lengths are in the scene's own units (metres for the Cornell box, "unit cube" for
// the rest); emission is radiosity (power per area); density is extinction per world unit.
// Every grid of a scene shares one transform: voxel (i,j,k) is the world cell
// [i vs, (i+1) vs] x [j vs, (j+1) vs] x [k vs, (k+1) vs], so its centre is ((i,j,k) + 0.5) vs.

#include "CanonicalGrids.h"
#include "vdbrad/core/Constants.h"

#include <openvdb/Exceptions.h>
#include <openvdb/Metadata.h>
#include <openvdb/math/Transform.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <utility>

namespace vdbrad {
namespace grids {

namespace {

using openvdb::Coord;
using openvdb::CoordBBox;
using openvdb::FloatGrid;
using openvdb::Vec3d;
using openvdb::Vec3f;
using openvdb::Vec3SGrid;


// ---- parameters --------------------------------------------------------------------------------

/// BuildParams with every default resolved and every value checked.
struct Params
{
    int res;
    float albedo, emission, radius, height, tau;
    unsigned seed;
};

[[noreturn]] void
fail(const std::string& scene, const std::string& what)
{
    OPENVDB_THROW(openvdb::ValueError, scene + ": " + what);
}

std::string
str(double v)
{
    std::ostringstream os;
    os << v;
    return os.str();
}

/// A negative value selects the default; NaN is not negative, so it reaches the checks and fails.
float
orDefault(float v, float def)
{
    return v < 0.f ? def : v;
}

Params
resolve(const std::string& scene, const BuildParams& in, float albedo, float emission,
    float radius, float height, float tau)
{
    if (in.res < 1 || in.res > 4096) fail(scene, "res " + str(in.res) + " is outside [1, 4096]");
    Params p;
    p.res = in.res;
    p.albedo = orDefault(in.albedo, albedo);
    p.emission = orDefault(in.emission, emission);
    p.radius = orDefault(in.radius, radius);
    p.height = orDefault(in.height, height);
    p.tau = orDefault(in.tau, tau);
    p.seed = in.seed;
    if (!(p.albedo >= 0.f && p.albedo <= 1.f)) {
        fail(scene, "albedo " + str(p.albedo) + " is outside [0, 1]");
    }
    if (!(p.emission >= 0.f && std::isfinite(p.emission))) {
        fail(scene, "emission " + str(p.emission) + " must be finite and >= 0");
    }
    // Geometry knobs a scene does not use keep their (harmless) value; finiteness is checked here,
    // positivity by the scenes that use them.
    if (!std::isfinite(p.radius) || !std::isfinite(p.height) || !std::isfinite(p.tau)) {
        fail(scene, "radius, height and tau must be finite");
    }
    return p;
}

// ---- grid plumbing -----------------------------------------------------------------------------

openvdb::math::Transform::Ptr
makeTransform(double vs)
{
    // Index (0,0,0) is the cell [0, vs]^3: the linear map puts voxel centres at i vs, the
    // half-voxel shift moves them to (i + 0.5) vs.
    auto xform = openvdb::math::Transform::createLinearTransform(vs);
    xform->postTranslate(Vec3d(vs / 2));
    return xform;
}

void
tag(openvdb::GridBase& grid, const std::string& name, const std::string& scene,
    const openvdb::math::Transform::Ptr& xform)
{
    grid.setName(name);
    grid.setTransform(xform);
    grid.insertMeta("vdbrad:scene", openvdb::StringMetadata(scene));
}

/// The three grids of a surface scene, filled voxel by voxel through accessors.
struct Surface
{
    Vec3SGrid::Ptr normal = Vec3SGrid::create(Vec3f(0.f));
    FloatGrid::Ptr emission = FloatGrid::create(0.f);
    Vec3SGrid::Accessor normalAcc = normal->getAccessor();
    FloatGrid::Accessor emissionAcc = emission->getAccessor();

    /// Emission is written even when zero so that the emission grid's topology is the normal's.
    void set(const Coord& ijk, const Vec3d& n, float e)
    {
        normalAcc.setValue(ijk, Vec3f(n.unitSafe()));
        emissionAcc.setValue(ijk, e);
    }

    /// Finishes a scene whose albedo is one value on every surface voxel.
    openvdb::GridPtrVec finish(const std::string& scene, double vs, float albedo)
    {
        auto albedoGrid = FloatGrid::create(FloatGrid::TreeType::Ptr(
            new FloatGrid::TreeType(normal->tree(), 0.f, albedo, openvdb::TopologyCopy())));
        return finish(scene, vs, albedoGrid);
    }

    openvdb::GridPtrVec finish(const std::string& scene, double vs, openvdb::GridBase::Ptr albedo)
    {
        auto xform = makeTransform(vs);
        normal->setVectorType(openvdb::VEC_COVARIANT_NORMALIZE);
        normal->setGridClass(openvdb::GRID_UNKNOWN);
        tag(*normal, "normal", scene, xform);
        tag(*albedo, "albedo", scene, xform);
        tag(*emission, "emission", scene, xform);
        return {normal, albedo, emission};
    }
};

openvdb::GridPtrVec
finishCloud(const std::string& scene, double vs, FloatGrid::Ptr density, float albedo)
{
    auto xform = makeTransform(vs);
    density->setGridClass(openvdb::GRID_FOG_VOLUME);
    tag(*density, "density", scene, xform);
    auto albedoGrid = FloatGrid::create(FloatGrid::TreeType::Ptr(
        new FloatGrid::TreeType(density->tree(), 0.f, albedo, openvdb::TopologyCopy())));
    tag(*albedoGrid, "albedo", scene, xform);
    return {density, albedoGrid};
}

/// Runs body(x0, x1) over [xmin, xmax] split into leaf-aligned (8-voxel) x ranges, in parallel.
/// Aligning keeps each range's voxels in leaves no other range touches, so per-range trees
/// merge by stealing leaves.
template<typename Body>
void
forLeafSlabs(int xmin, int xmax, const Body& body)
{
    if (xmax < xmin) return;
    const int first = xmin & ~7, count = ((xmax & ~7) - first) / 8 + 1;
    tbb::parallel_for(0, count, [&](int s) {
        const int x0 = std::max(xmin, first + 8 * s), x1 = std::min(xmax, first + 8 * s + 7);
        body(s, x0, x1);
    });
}

// ---- furnace box -------------------------------------------------------------------------------

openvdb::GridPtrVec
furnaceBox(const BuildParams& in)
{
    const std::string scene = "furnace-box";
    const Params p = resolve(scene, in, 0.5f, 1.f, 0.f, 0.f, 0.f);
    // With fewer than 3 voxels per side there is no interior for the shell to enclose.
    if (p.res < 3) fail(scene, "res " + str(p.res) + " leaves no interior (need >= 3)");
    const int n = p.res;
    Surface s;
    for (int i = 0; i < n; ++i) {
        for (int j = 0; j < n; ++j) {
            const bool edgeIJ = i == 0 || i == n - 1 || j == 0 || j == n - 1;
            for (int k = 0; k < n; k += (edgeIJ || k == n - 1) ? 1 : n - 1) {
                // Inward normal: sum of the inward normals of the faces the voxel lies on.
                Vec3d nrm(0.0);
                const int ijk[3] = {i, j, k};
                for (int a = 0; a < 3; ++a) {
                    if (ijk[a] == 0) nrm[a] += 1.0;
                    if (ijk[a] == n - 1) nrm[a] -= 1.0;
                }
                s.set(Coord(i, j, k), nrm, p.emission);
            }
        }
    }
    return s.finish(scene, 1.0 / n, p.albedo);
}

// ---- furnace sphere ----------------------------------------------------------------------------

std::int64_t
isqrt(std::int64_t v)
{
    if (v <= 0) return 0;
    auto r = static_cast<std::int64_t>(std::sqrt(static_cast<double>(v)));
    while (r * r > v) --r;
    while ((r + 1) * (r + 1) <= v) ++r;
    return r;
}

/// Voxels k of one column whose centre is strictly inside the sphere, given
/// rem = n^2 - (2i+1-n)^2 - (2j+1-n)^2: they satisfy (2k+1-n)^2 < rem. All in integers (the
/// doubled index offsets from the centre n/2 are exact), so the shell is exact at any res.
bool
insideRun(std::int64_t rem, int n, int& lo, int& hi)
{
    if (rem <= 0) return false;
    std::int64_t t = isqrt(rem - 1);              // largest t with t^2 < rem
    if ((t + n + 1) & 1) --t;                     // 2k+1-n has the parity of n+1
    if (t < 0) return false;
    lo = static_cast<int>((n - 1 - t) / 2);
    hi = static_cast<int>((n - 1 + t) / 2);
    return true;
}

openvdb::GridPtrVec
furnaceSphere(const BuildParams& in)
{
    const std::string scene = "furnace-sphere";
    const Params p = resolve(scene, in, 0.5f, 1.f, 0.f, 0.f, 0.f);
    const int n = p.res;
    const std::int64_t nn = std::int64_t(n) * n;
    auto d2 = [n](int i) { const std::int64_t d = 2 * std::int64_t(i) + 1 - n; return d * d; };

    // Every column's inside voxels are one run centred on the sphere's centre, so the union of
    // the runs of the 3x3 neighbouring columns is the longest of them; dilated by one voxel in k
    // it holds exactly the voxels with a 26-neighbour inside. The shell is that minus the inside.
    Surface s;
    for (int i = -1; i <= n; ++i) {
        for (int j = -1; j <= n; ++j) {
            int lo = 0, hi = -1, ownLo = 0, ownHi = -1;
            bool any = false;
            for (int di = -1; di <= 1; ++di) {
                for (int dj = -1; dj <= 1; ++dj) {
                    int a, b;
                    if (!insideRun(nn - d2(i + di) - d2(j + dj), n, a, b)) continue;
                    if (!any || a < lo) lo = a;
                    if (!any || b > hi) hi = b;
                    any = true;
                    if (di == 0 && dj == 0) { ownLo = a; ownHi = b; }
                }
            }
            if (!any) continue;
            for (int k = lo - 1; k <= hi + 1; ++k) {
                if (k >= ownLo && k <= ownHi) continue;
                // Towards the centre; the doubled offsets avoid any rounding.
                const Vec3d nrm(n - 1 - 2 * i, n - 1 - 2 * j, n - 1 - 2 * k);
                s.set(Coord(i, j, k), nrm, p.emission);
            }
        }
    }
    return s.finish(scene, 1.0 / n, p.albedo);
}

// ---- disk and plates ---------------------------------------------------------------------------

/// Receiver layer index for a gap h: the emitter layer is y = 0, so centre-to-centre distance is
/// (layer) * vs.
int
receiverLayer(const std::string& scene, double h, double vs)
{
    if (!(h > 0.0)) fail(scene, "height " + str(h) + " must be > 0");
    const double layer = std::round(h / vs);
    if (layer < 1.0) fail(scene, "height " + str(h) + " is under one voxel (" + str(vs) + ")");
    if (layer > 1 << 20) fail(scene, "height " + str(h) + " is too many voxels");
    return static_cast<int>(layer);
}

openvdb::GridPtrVec
disk(const BuildParams& in)
{
    const std::string scene = "disk";
    const Params p = resolve(scene, in, 1.f, 1.f, 0.25f, 0.25f, 0.f);
    const int n = p.res;
    const double vs = 1.0 / n, r = p.radius;
    if (!(r > 0.0)) fail(scene, "radius " + str(r) + " must be > 0");
    if (r > 0.5) fail(scene, "radius " + str(r) + " does not fit under the unit receiver");
    const int top = receiverLayer(scene, p.height, vs);

    Surface s;
    FloatGrid::Ptr albedo = FloatGrid::create(0.f);
    auto albedoAcc = albedo->getAccessor();
    // Disk voxels: centre within r of the axis x = z = 0.5, compared in doubled index units
    // (the axis is at doubled index n) so the test is exact.
    const double r2 = (2.0 * r * n) * (2.0 * r * n);
    std::size_t diskCount = 0;
    for (int i = 0; i < n; ++i) {
        for (int k = 0; k < n; ++k) {
            const double dx = 2 * i + 1 - n, dz = 2 * k + 1 - n;
            if (dx * dx + dz * dz <= r2) {
                s.set(Coord(i, 0, k), Vec3d(0, 1, 0), p.emission);
                albedoAcc.setValue(Coord(i, 0, k), 0.f);
                ++diskCount;
            }
            s.set(Coord(i, top, k), Vec3d(0, -1, 0), 0.f);
            albedoAcc.setValue(Coord(i, top, k), p.albedo);
        }
    }
    if (diskCount == 0) fail(scene, "radius " + str(r) + " covers no voxel centre at this res");
    return s.finish(scene, vs, albedo);
}

openvdb::GridPtrVec
plates(const BuildParams& in)
{
    const std::string scene = "plates";
    const Params p = resolve(scene, in, 1.f, 1.f, 0.f, 0.5f, 0.f);
    const int n = p.res;
    const double vs = 1.0 / n;
    const int top = receiverLayer(scene, p.height, vs);

    Surface s;
    FloatGrid::Ptr albedo = FloatGrid::create(0.f);
    auto albedoAcc = albedo->getAccessor();
    for (int i = 0; i < n; ++i) {
        for (int k = 0; k < n; ++k) {
            s.set(Coord(i, 0, k), Vec3d(0, 1, 0), p.emission);
            albedoAcc.setValue(Coord(i, 0, k), 0.f);
            s.set(Coord(i, top, k), Vec3d(0, -1, 0), 0.f);
            albedoAcc.setValue(Coord(i, top, k), p.albedo);
        }
    }
    return s.finish(scene, vs, albedo);
}

/// The lamp's parameters with its defaults (albedo 0.5, emission 1, half-side 0.05, height 0.25).
Params
lampParams(const BuildParams& in)
{
    return resolve("lamp", in, 0.5f, 1.f, 0.05f, 0.25f, 0.f);
}

/// The lamp's emitting columns lo..hi (both axes): centres within r of the axis x = z = 0.5,
/// compared in doubled index units (the axis is at doubled index n), so the test is exact; at
/// least the columns nearest the axis.
void
lampColumns(const std::string& scene, const Params& p, int& lo, int& hi)
{
    const int n = p.res;
    const double r = p.radius;
    if (!(r > 0.0)) fail(scene, "radius " + str(r) + " must be > 0");
    if (r > 0.5) fail(scene, "radius " + str(r) + " does not fit over the unit floor");
    lo = n;
    hi = -1;
    for (int i = 0; i < n; ++i) {
        if (std::abs(double(2 * i + 1 - n)) <= 2.0 * r * n) {
            lo = std::min(lo, i);
            hi = std::max(hi, i);
        }
    }
    // A lamp narrower than a voxel: the column (odd res) or two (even res) on the axis.
    if (hi < lo) {
        lo = (n - 1) / 2;
        hi = n / 2;
    }
}

openvdb::GridPtrVec
lamp(const BuildParams& in)
{
    const std::string scene = "lamp";
    const Params p = lampParams(in);
    const int n = p.res;
    const double vs = 1.0 / n;
    const int top = receiverLayer(scene, p.height, vs);
    int lo, hi;
    lampColumns(scene, p, lo, hi);

    Surface s;
    FloatGrid::Ptr albedo = FloatGrid::create(0.f);
    auto albedoAcc = albedo->getAccessor();
    for (int i = 0; i < n; ++i) {
        for (int k = 0; k < n; ++k) {
            s.set(Coord(i, 0, k), Vec3d(0, 1, 0), 0.f);
            albedoAcc.setValue(Coord(i, 0, k), p.albedo);
        }
    }
    for (int i = lo; i <= hi; ++i) {
        for (int k = lo; k <= hi; ++k) {
            s.set(Coord(i, top, k), Vec3d(0, -1, 0), p.emission);
            albedoAcc.setValue(Coord(i, top, k), 0.f);
        }
    }
    return s.finish(scene, vs, albedo);
}

// ---- Cornell box -------------------------------------------------------------------------------

/// A vertical prism over a convex quadrilateral footprint (x, z), from y = -infinity up to `top`.
/// The blocks stand on the solid floor, so extending them downwards changes no air and keeps
/// their bottom face from ever being taken as the nearest way out.
struct Prism
{
    std::array<double, 4> nx, nz, off;   // edge lines: nx x + nz z <= off inside (unit normals)
    double top;
    double xmin, xmax, zmin, zmax;

    Prism(const std::array<std::array<double, 2>, 4>& c, double topY): top(topY)
    {
        double area2 = 0.0;
        for (int e = 0; e < 4; ++e) {
            const auto &a = c[e], &b = c[(e + 1) % 4];
            area2 += a[0] * b[1] - b[0] * a[1];
        }
        // Outward normal of edge a->b is (dz, -dx) for a counter-clockwise (x, z) polygon.
        const double sgn = area2 > 0.0 ? 1.0 : -1.0;
        xmin = zmin = 1e300;
        xmax = zmax = -1e300;
        for (int e = 0; e < 4; ++e) {
            const auto &a = c[e], &b = c[(e + 1) % 4];
            const double ex = b[0] - a[0], ez = b[1] - a[1], len = std::sqrt(ex * ex + ez * ez);
            nx[e] = sgn * ez / len;
            nz[e] = -sgn * ex / len;
            off[e] = nx[e] * a[0] + nz[e] * a[1];
            xmin = std::min(xmin, a[0]); xmax = std::max(xmax, a[0]);
            zmin = std::min(zmin, a[1]); zmax = std::max(zmax, a[1]);
        }
    }

    /// Closed: the faces themselves are solid.
    bool contains(const Vec3d& p) const
    {
        if (p.y() > top || p.x() < xmin || p.x() > xmax || p.z() < zmin || p.z() > zmax) {
            return false;
        }
        for (int e = 0; e < 4; ++e) {
            if (nx[e] * p.x() + nz[e] * p.z() > off[e]) return false;
        }
        return true;
    }

    /// For @a p inside: the nearest point on the side faces or top, and that face's normal.
    /// For a convex footprint the foot on the nearest edge line lies on the edge itself.
    std::pair<Vec3d, Vec3d> exit(const Vec3d& p) const
    {
        double best = top - p.y();
        Vec3d normal(0, 1, 0), point(p.x(), top, p.z());
        for (int e = 0; e < 4; ++e) {
            const double depth = off[e] - (nx[e] * p.x() + nz[e] * p.z());
            if (depth < best) {
                best = depth;
                normal = Vec3d(nx[e], 0, nz[e]);
                point = p + depth * normal;
            }
        }
        return {point, normal};
    }
};

enum class Wall { None, Left, Right, Floor, Ceiling, Back };

/// Cornell's measured geometry (metres). The room is open at z = 0 (the camera side).
struct CornellRoom
{
    const double X = 0.556, Y = 0.5488, Z = 0.5592;
    const std::array<Prism, 2> blocks{
        Prism({{{0.130, 0.065}, {0.082, 0.225}, {0.240, 0.272}, {0.290, 0.114}}}, 0.165),
        Prism({{{0.423, 0.247}, {0.265, 0.296}, {0.314, 0.456}, {0.472, 0.406}}}, 0.330)};

    /// Air: strictly inside the room and outside both blocks. Outside the room is void, not air.
    bool air(const Vec3d& p) const
    {
        if (!(p.x() > 0 && p.x() < X && p.y() > 0 && p.y() < Y && p.z() > 0 && p.z() < Z)) {
            return false;
        }
        return !blocks[0].contains(p) && !blocks[1].contains(p);
    }

    /// Normal into the air at solid point @a p (direction to an approximately nearest air point,
    /// which blends wall normals at the room's edges) and the wall it belongs to (None: a block).
    std::pair<Vec3d, Wall> surface(const Vec3d& p) const
    {
        // Nearest point of the room's closure; the open front (z < 0) is never reached from the
        // surface voxels, which all have centres at z > 0. A centre exactly on a wall's plane is
        // solid, so it counts as 1e-12 m outside: its normal is then that wall's.
        const Vec3d q(std::clamp(p.x(), 0.0, X), std::clamp(p.y(), 0.0, Y),
            std::clamp(p.z(), 0.0, Z));
        const Vec3d hi(X, Y, Z);
        Vec3d toRoom = q - p;
        for (int b = 0; b < 3; ++b) {
            if (p[b] <= 0.0) toRoom[b] += 1e-12;
            else if (p[b] >= hi[b]) toRoom[b] -= 1e-12;
        }
        Wall wall = Wall::None;
        int a = 0;   // the axis the point lies furthest out along
        for (int b = 1; b < 3; ++b) {
            if (std::abs(toRoom[b]) > std::abs(toRoom[a])) a = b;
        }
        if (toRoom[a] != 0.0) {
            if (a == 0) wall = toRoom[a] > 0 ? Wall::Right : Wall::Left;
            else if (a == 1) wall = toRoom[a] > 0 ? Wall::Floor : Wall::Ceiling;
            else wall = Wall::Back;
        }
        for (const Prism& b : blocks) {
            if (!b.contains(q)) continue;
            const auto [out, faceNormal] = b.exit(q);
            const Vec3d d = out - p;
            // A point exactly on a face has no direction to go; the face's normal is the answer.
            const Vec3d n = d.length() > 1e-12 ? d.unit() : faceNormal;
            return {n, wall};   // None inside a block; Floor under one
        }
        return {toRoom.unitSafe(), wall};
    }
};

struct CornellVoxel
{
    Coord ijk;
    Vec3f normal;
    Wall wall;
    bool light;
};

openvdb::GridPtrVec
cornell(const BuildParams& in)
{
    const std::string scene = "cornell";
    // Colours are Cornell's measured ones; `albedo` is checked but not used.
    const Params p = resolve(scene, in, 0.73f, 1.f, 0.f, 0.f, 0.f);
    const CornellRoom room;
    const double vs = room.Z / p.res;   // z is the longest axis
    auto centre = [vs](int i, int j, int k) {
        return Vec3d((i + 0.5) * vs, (j + 0.5) * vs, (k + 0.5) * vs);
    };
    // Any voxel with a 26-neighbour in the air lies in these index ranges (k >= 0: the front is
    // open, so nothing is built at z < 0).
    const int iMax = int(std::floor(room.X / vs)) + 1, jMax = int(std::floor(room.Y / vs)) + 1;
    const int kMax = int(std::floor(room.Z / vs)) + 1;

    // Index boxes (2 voxels of margin) of the blocks: the only solid deep inside the room.
    struct Box { int i0, i1, j1, k0, k1; };
    std::array<Box, 2> blockBox;
    for (int b = 0; b < 2; ++b) {
        const Prism& pr = room.blocks[b];
        blockBox[b] = {int(std::floor(pr.xmin / vs)) - 2, int(std::floor(pr.xmax / vs)) + 2,
            int(std::floor(pr.top / vs)) + 2, int(std::floor(pr.zmin / vs)) - 2,
            int(std::floor(pr.zmax / vs)) + 2};
    }

    auto isSurface = [&](int i, int j, int k) {
        if (room.air(centre(i, j, k))) return false;
        // Face neighbours first: most surface voxels have one in the air.
        static constexpr int face[6][3] = {
            {1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
        for (const auto& d : face) {
            if (room.air(centre(i + d[0], j + d[1], k + d[2]))) return true;
        }
        for (int di = -1; di <= 1; ++di) {
            for (int dj = -1; dj <= 1; ++dj) {
                for (int dk = -1; dk <= 1; ++dk) {
                    if (std::abs(di) + std::abs(dj) + std::abs(dk) < 2) continue;
                    if (room.air(centre(i + di, j + dj, k + dk))) return true;
                }
            }
        }
        return false;
    };

    const double lx0 = 0.213, lx1 = 0.343, lz0 = 0.227, lz1 = 0.332;
    const int slabs = ((iMax & ~7) - (-1 & ~7)) / 8 + 1;
    std::vector<std::vector<CornellVoxel>> found(slabs);
    forLeafSlabs(-1, iMax, [&](int slab, int x0, int x1) {
        auto& out = found[slab];
        std::vector<std::pair<int, int>> runs;
        for (int i = x0; i <= x1; ++i) {
            for (int j = -1; j <= jMax; ++j) {
                // k runs worth visiting in this column: all of it near the side walls, floor and
                // ceiling; otherwise only near the back and front and through the blocks.
                runs.clear();
                if (i < 3 || i > iMax - 3 || j < 3 || j > jMax - 3) {
                    runs.emplace_back(0, kMax);
                } else {
                    runs.emplace_back(0, 2);
                    runs.emplace_back(kMax - 3, kMax);
                    for (const Box& b : blockBox) {
                        if (i >= b.i0 && i <= b.i1 && j <= b.j1) runs.emplace_back(b.k0, b.k1);
                    }
                    std::sort(runs.begin(), runs.end());
                }
                int next = 0;   // first k not yet visited: runs may overlap
                for (const auto& [r0, r1] : runs) {
                    for (int k = std::max(r0, next); k <= std::min(r1, kMax); ++k) {
                        if (!isSurface(i, j, k)) continue;
                        const Vec3d c = centre(i, j, k);
                        const auto [n, wall] = room.surface(c);
                        const bool light = wall == Wall::Ceiling && c.x() >= lx0 &&
                            c.x() <= lx1 && c.z() >= lz0 && c.z() <= lz1;
                        out.push_back({Coord(i, j, k), Vec3f(n), wall, light});
                    }
                    next = std::max(next, r1 + 1);
                }
            }
        }
    });

    const Vec3f white(0.73f, 0.73f, 0.73f), red(0.63f, 0.065f, 0.05f), green(0.14f, 0.45f, 0.091f);
    Surface s;
    Vec3SGrid::Ptr albedo = Vec3SGrid::create(Vec3f(0.f));
    albedo->setVectorType(openvdb::VEC_INVARIANT);
    auto albedoAcc = albedo->getAccessor();
    for (const auto& voxels : found) {
        for (const CornellVoxel& v : voxels) {
            s.set(v.ijk, Vec3d(v.normal), v.light ? p.emission : 0.f);
            albedoAcc.setValue(v.ijk,
                v.wall == Wall::Left ? red : v.wall == Wall::Right ? green : white);
        }
    }
    openvdb::GridPtrVec grids = s.finish(scene, vs, albedo);
    if (p.tau > 0.f) {
        // A uniform fog in the room's air, of optical depth tau across its width (x).
        auto density = FloatGrid::create(0.f);
        const float sigma = float(p.tau / room.X);
        auto acc = density->getAccessor();
        for (int i = 0; i <= iMax; ++i) {
            for (int j = 0; j <= jMax; ++j) {
                for (int k = 0; k <= kMax; ++k) {
                    if (room.air(centre(i, j, k))) acc.setValue(Coord(i, j, k), sigma);
                }
            }
        }
        density->setGridClass(openvdb::GRID_FOG_VOLUME);
        tag(*density, "density", scene, makeTransform(vs));
        grids.push_back(density);
    } else if (p.tau < 0.f) {
        fail(scene, "tau " + str(p.tau) + " must be >= 0");
    }
    return grids;
}

// ---- slab --------------------------------------------------------------------------------------

openvdb::GridPtrVec
slab(const BuildParams& in)
{
    const std::string scene = "slab";
    const Params p = resolve(scene, in, 1.f, 0.f, 0.f, 0.f, 10.f);
    if (!(p.tau > 0.f)) fail(scene, "tau " + str(p.tau) + " must be > 0");
    const int n = p.res, ny = std::max(1, int(std::lround(n / 4.0)));
    const double vs = 1.0 / n;
    // Per world unit, so that the ny voxels of a column sum to exactly tau.
    const float sigma = float(p.tau / (ny * vs));
    auto density = FloatGrid::create(0.f);
    density->denseFill(CoordBBox(Coord(0), Coord(n - 1, ny - 1, n - 1)), sigma, true);
    return finishCloud(scene, vs, density, p.albedo);
}

// ---- step cloud --------------------------------------------------------------------------------

openvdb::GridPtrVec
stepCloud(const BuildParams& in)
{
    const std::string scene = "step-cloud";
    const Params p = resolve(scene, in, 1.f, 0.f, 0.f, 0.f, 18.f);
    if (!(p.tau > 0.f)) fail(scene, "tau " + str(p.tau) + " must be > 0");
    if (p.res % 32 != 0) fail(scene, "res " + str(p.res) + " must be a multiple of 32 (columns)");
    // Kilometres: 0.5 wide, 0.25 high, one voxel deep (the medium is uniform along z).
    const int n = p.res, ny = n / 2, perColumn = n / 32;
    const double vs = 0.5 / n;
    const float thin = float(p.tau / 9.0 / 0.25), thick = float(p.tau / 0.25);
    auto density = FloatGrid::create(0.f);
    density->denseFill(CoordBBox(Coord(0), Coord(16 * perColumn - 1, ny - 1, 0)), thin, true);
    density->denseFill(CoordBBox(Coord(16 * perColumn, 0, 0), Coord(n - 1, ny - 1, 0)), thick,
        true);
    return finishCloud(scene, vs, density, p.albedo);
}

// ---- cumulus -----------------------------------------------------------------------------------

// Only integer hashing and + - * / sqrt (all exactly rounded in IEEE 754) feed the shape, so a
// seed gives the same cloud on every platform (barring compilers that contract to FMA).

std::uint64_t
mix(std::uint64_t z)
{
    // splitmix64's finaliser: a bijection with good avalanche.
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

struct Rng
{
    std::uint64_t state;
    std::uint64_t next() { return mix(state += 0x9E3779B97F4A7C15ull); }
    double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }   // [0,1)
};

double
smoothstep(double e0, double e1, double x)
{
    const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

/// Value noise in [0, 1): hashed lattice values, smoothly interpolated.
double
valueNoise(double x, double y, double z, std::uint64_t seed)
{
    const double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
    const auto ix = std::int64_t(fx), iy = std::int64_t(fy), iz = std::int64_t(fz);
    auto lattice = [seed](std::int64_t a, std::int64_t b, std::int64_t c) {
        std::uint64_t h = mix(seed ^ std::uint64_t(a) * 0x8CB92BA72F3D8DD7ull);
        h = mix(h ^ std::uint64_t(b) * 0xD6E8FEB86659FD93ull);
        h = mix(h ^ std::uint64_t(c) * 0xA0761D6478BD642Full);
        return double(h >> 11) * (1.0 / 9007199254740992.0);
    };
    auto fade = [](double t) { return t * t * (3.0 - 2.0 * t); };
    const double u = fade(x - fx), v = fade(y - fy), w = fade(z - fz);
    auto lerp = [](double a, double b, double t) { return a + (b - a) * t; };
    double c[2][2];
    for (int a = 0; a < 2; ++a) {
        for (int b = 0; b < 2; ++b) {
            c[a][b] = lerp(lattice(ix + a, iy + b, iz), lattice(ix + a, iy + b, iz + 1), w);
        }
    }
    return lerp(lerp(c[0][0], c[0][1], v), lerp(c[1][0], c[1][1], v), u);
}

class Cumulus
{
public:
    explicit Cumulus(unsigned seed): mSeed(mix(0xC0FFEEull + seed))
    {
        Rng rng{mSeed};
        const int count = 10 + int(rng.next() % 21);
        // A large central puff guarantees the centre column is cloud; the others heap around it,
        // higher near the axis (a dome), all reaching below the flat base.
        mSpheres.push_back({0.5, kBase + 0.20 + 0.05 * rng.uniform(), 0.5,
            0.20 + 0.05 * rng.uniform()});
        while (int(mSpheres.size()) < count) {
            const double dx = 0.6 * rng.uniform() - 0.3, dz = 0.6 * rng.uniform() - 0.3;
            const double rho = std::sqrt(dx * dx + dz * dz);
            if (rho > 0.3) continue;   // rejection keeps the footprint round without trig
            const double r = 0.08 + 0.10 * rng.uniform();
            double y = kBase + 0.5 * r + 0.45 * (1.0 - rho / 0.3) * rng.uniform();
            // Keep every puff inside the unit cube with a margin for the smooth edge.
            const double lo = r + 0.03, hi = 0.97 - r;
            y = std::clamp(y, lo, hi);
            mSpheres.push_back({std::clamp(0.5 + dx, lo, hi), y, std::clamp(0.5 + dz, lo, hi), r});
        }
    }

    /// Unscaled density in [0, 1].
    double operator()(const Vec3d& p) const
    {
        if (p.y() <= kBase) return 0.0;
        double cover = -1.0;   // > 0 inside some puff, 1 at a puff's centre
        for (const Sphere& s : mSpheres) {
            const double dx = p.x() - s.x, dy = p.y() - s.y, dz = p.z() - s.z;
            const double d2 = dx * dx + dy * dy + dz * dz;
            if (d2 >= s.r * s.r) continue;
            cover = std::max(cover, 1.0 - std::sqrt(d2) / s.r);
        }
        if (cover <= 0.0) return 0.0;
        // Three octaves of value noise eat into the edge; the core (cover near 1) survives.
        const double f = 7.0;
        const double noise = (4.0 * valueNoise(f * p.x(), f * p.y(), f * p.z(), mSeed) +
            2.0 * valueNoise(2 * f * p.x(), 2 * f * p.y(), 2 * f * p.z(), mSeed + 1) +
            valueNoise(4 * f * p.x(), 4 * f * p.y(), 4 * f * p.z(), mSeed + 2)) / 7.0;
        const double eroded = cover - 0.3 * noise;
        return smoothstep(0.0, 0.25, eroded) * smoothstep(kBase, kBase + 0.04, p.y());
    }

    /// World bounds of the puffs (the density is zero outside).
    void bounds(Vec3d& lo, Vec3d& hi) const
    {
        lo = Vec3d(1e300);
        hi = Vec3d(-1e300);
        for (const Sphere& s : mSpheres) {
            lo = openvdb::math::minComponent(lo, Vec3d(s.x - s.r, s.y - s.r, s.z - s.r));
            hi = openvdb::math::maxComponent(hi, Vec3d(s.x + s.r, s.y + s.r, s.z + s.r));
        }
    }

private:
    struct Sphere { double x, y, z, r; };
    static constexpr double kBase = 0.22;   // flat cloud base (world y)
    std::uint64_t mSeed;
    std::vector<Sphere> mSpheres;
};

openvdb::GridPtrVec
cumulus(const BuildParams& in)
{
    const std::string scene = "cumulus";
    const Params p = resolve(scene, in, 1.f, 0.f, 0.f, 0.f, 20.f);
    if (!(p.tau > 0.f)) fail(scene, "tau " + str(p.tau) + " must be > 0");
    const int n = p.res;
    const double vs = 1.0 / n;
    const Cumulus shape(p.seed);
    auto centre = [vs](int i, int j, int k) {
        return Vec3d((i + 0.5) * vs, (j + 0.5) * vs, (k + 0.5) * vs);
    };

    // Scale from the centre column (index res/2, res/2), evaluated in double before any rounding
    // to float, so the stored column sums to tau up to float rounding.
    auto columnPath = [&](int i, int k) {
        double sum = 0.0;
        for (int j = 0; j < n; ++j) sum += shape(centre(i, j, k));
        return sum * vs;
    };
    int ci = n / 2, ck = n / 2;
    double path = columnPath(ci, ck);
    if (!(path > 0.0)) {
        // Coarse grids can miss the central puff: fall back to the densest column.
        for (int i = 0; i < n; ++i) {
            for (int k = 0; k < n; ++k) {
                const double c = columnPath(i, k);
                if (c > path) { path = c; ci = i; ck = k; }
            }
        }
        if (!(path > 0.0)) fail(scene, "res " + str(n) + " is too coarse to hold any cloud");
    }
    const double scale = p.tau / path;

    Vec3d lo, hi;
    shape.bounds(lo, hi);
    auto toIndex = [&](double w, int bias) {
        return std::clamp(int(std::floor(w / vs)) + bias, 0, n - 1);
    };
    const CoordBBox box(Coord(toIndex(lo.x(), -1), toIndex(lo.y(), -1), toIndex(lo.z(), -1)),
        Coord(toIndex(hi.x(), 1), toIndex(hi.y(), 1), toIndex(hi.z(), 1)));
    const int slabs = ((box.max().x() & ~7) - (box.min().x() & ~7)) / 8 + 1;
    std::vector<FloatGrid::Ptr> parts(slabs);
    forLeafSlabs(box.min().x(), box.max().x(), [&](int s, int x0, int x1) {
        auto part = FloatGrid::create(0.f);
        auto acc = part->getAccessor();
        for (int i = x0; i <= x1; ++i) {
            for (int j = box.min().y(); j <= box.max().y(); ++j) {
                for (int k = box.min().z(); k <= box.max().z(); ++k) {
                    // Stored only where the float stays positive: active means density > 0.
                    const float d = float(scale * shape(centre(i, j, k)));
                    if (d > 0.f) acc.setValue(Coord(i, j, k), d);
                }
            }
        }
        parts[s] = part;
    });
    auto density = FloatGrid::create(0.f);
    for (auto& part : parts) {
        if (part) density->tree().merge(part->tree());
    }
    return finishCloud(scene, vs, density, p.albedo);
}

} // namespace

// ---- public builders ---------------------------------------------------------------------------

openvdb::GridPtrVec makeFurnaceBox(const BuildParams& p) { return furnaceBox(p); }
openvdb::GridPtrVec makeFurnaceSphere(const BuildParams& p) { return furnaceSphere(p); }
openvdb::GridPtrVec makeDisk(const BuildParams& p) { return disk(p); }
openvdb::GridPtrVec makePlates(const BuildParams& p) { return plates(p); }
openvdb::GridPtrVec makeLamp(const BuildParams& p) { return lamp(p); }
openvdb::GridPtrVec makeCornell(const BuildParams& p) { return cornell(p); }
openvdb::GridPtrVec makeSlab(const BuildParams& p) { return slab(p); }
openvdb::GridPtrVec makeCumulus(const BuildParams& p) { return cumulus(p); }
openvdb::GridPtrVec makeStepCloud(const BuildParams& p) { return stepCloud(p); }

const std::vector<Builder>&
builders()
{
    static const std::vector<Builder> all{
        {"furnace-box", "closed unit cube shell, albedo 0.5, emission 1: every radiosity is "
            "E/(1-rho) = 2", makeFurnaceBox},
        {"furnace-sphere", "closed sphere shell of diameter 1, albedo 0.5, emission 1: every "
            "radiosity is E/(1-rho) = 2", makeFurnaceSphere},
        {"disk", "emitting disk r=0.25 under a unit receiver at h=0.25: receiver radiosity "
            "E/2 (1 - (h^2+a^2-r^2)/sqrt((h^2+a^2+r^2)^2 - 4a^2r^2)), 0.5 on axis", makeDisk},
        {"plates", "emitting unit square under an albedo-1 unit square at h=0.5: mean receiver "
            "radiosity E F, F = 0.41525 (parallel squares)", makePlates},
        {"lamp", "square emitter of half-side r=0.05 facing down at h=0.25 over a unit floor of "
            "albedo 0.5: floor radiosity rho E F(point -> square), Howell B-3", makeLamp},
        {"cornell", "Cornell box (metres, RGB albedo, ceiling light); with tau > 0 a uniform "
            "fog of optical depth tau across its width (`density`); no closed-form answer",
            makeCornell},
        {"slab", "homogeneous cloud slab 1 x 0.25 x 1, vertical optical thickness tau = 10, "
            "albedo 1; periodic in x and z", makeSlab},
        {"cumulus", "seeded procedural cumulus in the unit cube, centre-column optical path "
            "tau = 20, albedo 1; no closed-form answer", makeCumulus},
        {"step-cloud", "I3RC step cloud (km): 32 columns over 0.5 x 0.25, optical thickness "
            "tau / 9 = 2 then tau = 18, albedo 1, one voxel deep; periodic in x and z",
            makeStepCloud},
    };
    return all;
}

const Builder*
findBuilder(const std::string& name)
{
    for (const Builder& b : builders()) {
        if (b.name == name) return &b;
    }
    return nullptr;
}

// ---- exact answers -----------------------------------------------------------------------------

double
diskIrradiance(double E, double r, double h, double a)
{
    if (!(r >= 0.0) || !(h > 0.0)) {
        OPENVDB_THROW(openvdb::ValueError, "diskIrradiance: need r >= 0 and h > 0");
    }
    const double h2 = h * h, a2 = a * a, r2 = r * r;
    const double s = h2 + a2 + r2;
    return 0.5 * E * (1.0 - (h2 + a2 - r2) / std::sqrt(s * s - 4.0 * a2 * r2));
}

double
rectangleFactor(double x0, double x1, double z0, double z1, double h)
{
    if (!(h > 0.0)) OPENVDB_THROW(openvdb::ValueError, "rectangleFactor: need h > 0");
    // Factor to [0, x] x [0, z] for a corner at the foot of the normal (B-3). It is odd in x and
    // in z, which is exactly the sign an oriented corner needs, so the inclusion-exclusion sum
    // below also covers rectangles that do not contain the foot point.
    auto corner = [h](double x, double z) {
        const double X = x / h, Y = z / h;
        const double sx = std::sqrt(1.0 + X * X), sy = std::sqrt(1.0 + Y * Y);
        return (X / sx * std::atan(Y / sx) + Y / sy * std::atan(X / sy)) / (2.0 * kPi);
    };
    return corner(x1, z1) - corner(x0, z1) - corner(x1, z0) + corner(x0, z0);
}

double
lampFloorRadiosity(const BuildParams& in, int i, int k)
{
    const std::string scene = "lamp";
    const Params p = lampParams(in);
    const int n = p.res;
    const double vs = 1.0 / n;
    const double h = receiverLayer(scene, p.height, vs) * vs;
    int lo, hi;
    lampColumns(scene, p, lo, hi);
    // Voxel c spans [c, c + 1) vs in world units (its centre at (c + 1/2) vs).
    const double x = (i + 0.5) * vs, z = (k + 0.5) * vs, a = lo * vs, b = (hi + 1) * vs;
    return double(p.albedo) * p.emission * rectangleFactor(a - x, b - x, a - z, b - z, h);
}

double
parallelSquaresViewFactor(double w, double h)
{
    if (!(w > 0.0) || !(h > 0.0)) {
        OPENVDB_THROW(openvdb::ValueError, "parallelSquaresViewFactor: need w > 0 and h > 0");
    }
    // C-11 with a = b = w, so X = Y.
    const double X = w / h, Y = X;
    const double x2 = 1.0 + X * X, y2 = 1.0 + Y * Y;
    const double sx = std::sqrt(x2), sy = std::sqrt(y2);
    const double bracket = 0.5 * std::log(x2 * y2 / (x2 + Y * Y)) + X * sy * std::atan(X / sy) +
        Y * sx * std::atan(Y / sx) - X * std::atan(X) - Y * std::atan(Y);
    return 2.0 / (kPi * X * Y) * bracket;
}

} // namespace grids
} // namespace vdbrad
