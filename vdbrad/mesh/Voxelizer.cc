#include "vdbrad/mesh/Voxelizer.h"

#include "vdbrad/core/Errors.h"
#include "vdbrad/core/GridContract.h"

#include <openvdb/tools/MeshToVolume.h>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace vdbrad {

using openvdb::Coord;
using openvdb::Vec3d;
using openvdb::Vec3f;

namespace {

// Tolerance of the exact tests, in index units (voxels): touching counts as meeting, and a
// crossing exactly on an edge shared by two triangles must not slip between them through
// rounding. Index coordinates stay below 2^30, so double rounding is far below this.
constexpr double kTouch = 1e-9;

double cross2(double ax, double ay, double bx, double by) { return ax * by - ay * bx; }

// Does the closed segment from @a p to @a q meet the closed segment from @a a to @a b? (Squared
// distance between two segments, for squaredDistanceToTriangle.)
double
squaredDistanceToSegment(const Vec3d& p, const Vec3d& a, const Vec3d& b)
{
    const Vec3d ab = b - a;
    const double len2 = ab.lengthSqr();
    const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
    return (a + t * ab - p).lengthSqr();
}

// Area (voxel faces) of the triangle (a, b, c) inside the cube of the voxel at @a centre:
// Sutherland-Hodgman against the cube's six planes, then the polygon's vector area.
double
areaInVoxel(const Vec3d& centre, const Vec3d& a, const Vec3d& b, const Vec3d& c)
{
    std::vector<Vec3d> poly{a, b, c}, next;
    for (int k = 0; k < 3 && !poly.empty(); ++k) {
        for (const double side : {-1.0, 1.0}) {
            // Keep side * (x_k - centre_k) <= 1/2.
            next.clear();
            const size_t m = poly.size();
            for (size_t i = 0; i < m; ++i) {
                const Vec3d& p = poly[i];
                const Vec3d& q = poly[(i + 1) % m];
                const double dp = 0.5 - side * (p[k] - centre[k]);
                const double dq = 0.5 - side * (q[k] - centre[k]);
                if (dp >= 0.0) next.push_back(p);
                if ((dp >= 0.0) != (dq >= 0.0)) next.push_back(p + (q - p) * (dp / (dp - dq)));
            }
            poly.swap(next);
        }
    }
    Vec3d sum(0.0);
    for (size_t i = 0; i + 2 < poly.size(); ++i) {
        sum += (poly[i + 1] - poly[0]).cross(poly[i + 2] - poly[0]);
    }
    return 0.5 * sum.length();
}

// Emitting mesh inside one voxel: what `emission` and `emission_area` are made of.
struct EmitHit
{
    Coord ijk;
    float area;        // voxel faces
    uint32_t triangle;

    bool operator<(const EmitHit& o) const
    {
        if (ijk != o.ijk) return ijk < o.ijk;
        if (area != o.area) return area > o.area;   // the largest first
        return triangle < o.triangle;
    }
};

struct Hit
{
    Coord ijk;
    float distance2;   // squared distance from the voxel centre to the triangle, voxels^2
    uint32_t triangle;

    bool operator<(const Hit& o) const
    {
        if (ijk != o.ijk) return ijk < o.ijk;
        if (distance2 != o.distance2) return distance2 < o.distance2;
        return triangle < o.triangle;   // ties: the lower index, so the result is deterministic
    }
};

// Width, along n, of the band of voxel centres whose cube (thick) or star meets the plane
// n.x = d: the largest |n.step| over the steps the shell must stop (26: ||n||_1; star:
// ||n||_1 - min |n_k|, the largest face diagonal).
double
planeThickness(const Vec3d& n, bool thick)
{
    const double l1 = std::abs(n[0]) + std::abs(n[1]) + std::abs(n[2]);
    return thick ? l1 : l1 - std::min({std::abs(n[0]), std::abs(n[1]), std::abs(n[2])});
}

bool isGrey(const Vec3f& c) { return c[0] == c[1] && c[1] == c[2]; }

} // namespace

// ---- exact tests --------------------------------------------------------------------------------

bool
triangleMeetsVoxel(const Vec3d& centre, const Vec3d& a0, const Vec3d& b0, const Vec3d& c0)
{
    // Separating-axis theorem for a triangle and the cube of half-size h around the origin: they
    // are disjoint iff their projections are disjoint on one of 13 axes (the 3 cube normals, the
    // triangle's normal, and the 9 products of a cube edge with a triangle edge).
    const double h = 0.5 + kTouch;
    const Vec3d v[3] = {a0 - centre, b0 - centre, c0 - centre};
    for (int k = 0; k < 3; ++k) {
        if (std::min({v[0][k], v[1][k], v[2][k]}) > h) return false;
        if (std::max({v[0][k], v[1][k], v[2][k]}) < -h) return false;
    }
    const Vec3d e[3] = {v[1] - v[0], v[2] - v[1], v[0] - v[2]};
    auto separates = [&](const Vec3d& axis) {
        const double r = h * (std::abs(axis[0]) + std::abs(axis[1]) + std::abs(axis[2]));
        const double p0 = axis.dot(v[0]), p1 = axis.dot(v[1]), p2 = axis.dot(v[2]);
        return std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r;
    };
    if (separates(e[0].cross(e[1]))) return false;
    for (int k = 0; k < 3; ++k) {
        Vec3d unit(0.0);
        unit[k] = 1.0;
        for (const Vec3d& edge : e) {
            // A zero axis (edge parallel to the cube's edge) separates nothing: r = p = 0.
            if (separates(unit.cross(edge))) return false;
        }
    }
    return true;
}

bool
triangleMeetsVoxelStar(const Vec3d& centre, const Vec3d& a, const Vec3d& b, const Vec3d& c)
{
    // The 3 axis steps and the 6 in-plane diagonal steps, each as a segment through the centre.
    static const Vec3d kSteps[9] = {Vec3d(1, 0, 0), Vec3d(0, 1, 0), Vec3d(0, 0, 1),
        Vec3d(1, 1, 0), Vec3d(1, -1, 0), Vec3d(1, 0, 1), Vec3d(1, 0, -1), Vec3d(0, 1, 1),
        Vec3d(0, 1, -1)};
    const Vec3d n = (b - a).cross(c - a);
    const double scale = (b - a).lengthSqr() + (c - b).lengthSqr() + (a - c).lengthSqr();
    // Inside test in the projection along the dominant axis of n, where the triangle keeps
    // most of its area.
    const int m = int(std::abs(n[0]) >= std::abs(n[1])
        ? (std::abs(n[0]) >= std::abs(n[2]) ? 0 : 2) : (std::abs(n[1]) >= std::abs(n[2]) ? 1 : 2));
    if (!(std::abs(n[m]) > 0.0)) return false;
    const int u = (m + 1) % 3, w = (m + 2) % 3;
    const double sign = n[m] > 0.0 ? 1.0 : -1.0;
    // w_i below is an edge length times a distance: kTouch voxels of slack.
    const double tol = kTouch * std::sqrt(scale);
    for (const Vec3d& step : kSteps) {
        const double along = n.dot(step);
        // A step parallel to the plane meets it only if it lies in it; the steps that cross
        // the plane at the same points then decide.
        if (std::abs(along) <= 1e-12 * scale) continue;
        const double s = n.dot(a - centre) / along;   // centre + s step lies on the plane
        if (std::abs(s) > 0.5 + kTouch) continue;
        const Vec3d p = centre + s * step;
        const double w0 = cross2(b[u] - a[u], b[w] - a[w], p[u] - a[u], p[w] - a[w]);
        const double w1 = cross2(c[u] - b[u], c[w] - b[w], p[u] - b[u], p[w] - b[w]);
        const double w2 = cross2(a[u] - c[u], a[w] - c[w], p[u] - c[u], p[w] - c[w]);
        if (sign * w0 >= -tol && sign * w1 >= -tol && sign * w2 >= -tol) return true;
    }
    return false;
}

double
squaredDistanceToTriangle(const Vec3d& p, const Vec3d& a, const Vec3d& b, const Vec3d& c)
{
    const Vec3d n = (b - a).cross(c - a);
    const double n2 = n.lengthSqr();
    if (n2 > 0.0) {
        // Foot of the perpendicular inside the triangle: the plane distance is the answer.
        const Vec3d q = p - (n.dot(p - a) / n2) * n;
        if (n.dot((b - a).cross(q - a)) >= 0.0 && n.dot((c - b).cross(q - b)) >= 0.0
            && n.dot((a - c).cross(q - c)) >= 0.0) {
            return (p - q).lengthSqr();
        }
    }
    return std::min({squaredDistanceToSegment(p, a, b), squaredDistanceToSegment(p, b, c),
        squaredDistanceToSegment(p, c, a)});
}

// ---- voxelizeMesh -------------------------------------------------------------------------------

double
voxelizeVoxelSize(const TriangleMesh& mesh, const VoxelizeOptions& options)
{
    if (options.voxelSize != 0.0) {
        if (!(options.voxelSize > 0.0) || !std::isfinite(options.voxelSize)) {
            std::ostringstream os;
            os << "voxel size must be a positive finite number, got " << options.voxelSize;
            OPENVDB_THROW(openvdb::ValueError, os.str());
        }
        return options.voxelSize;
    }
    if (options.resolution < 1 || options.resolution > 16384) {
        OPENVDB_THROW(openvdb::ValueError, "resolution must be in [1, 16384], got "
            << options.resolution);
    }
    openvdb::BBoxd box;
    for (const Vec3f& p : mesh.points) box.expand(Vec3d(p));
    const double extent = box.extents()[box.maxExtent()];
    if (!(extent > 0.0)) {
        OPENVDB_THROW(openvdb::ValueError, "the mesh has no extent (all points coincide)");
    }
    return extent / options.resolution;
}

// ---- voxelizeMesh: its steps --------------------------------------------------------------------

namespace {

// Options and mesh are checked before anything is computed from them (the first error found,
// in this order, is the one reported).
void
checkVoxelizeInput(const TriangleMesh& mesh, const VoxelizeOptions& options)
{
    if (options.separation != 6 && options.separation != 26) {
        OPENVDB_THROW(openvdb::ValueError, "separation must be 6 or 26, got "
            << options.separation);
    }
    if (!(options.defaultAlbedo >= 0.f && options.defaultAlbedo <= 1.f)) {
        OPENVDB_THROW(openvdb::ValueError, "default albedo must be in [0, 1], got "
            << options.defaultAlbedo);
    }
    for (size_t i = 0; i < mesh.points.size(); ++i) {
        const Vec3f& p = mesh.points[i];
        if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
            OPENVDB_THROW(openvdb::ValueError, "point " << i + 1 << " is not finite");
        }
    }
    for (const openvdb::Vec3I& t : mesh.triangles) {
        if (t[0] >= mesh.points.size() || t[1] >= mesh.points.size()
            || t[2] >= mesh.points.size()) {
            OPENVDB_THROW(openvdb::ValueError, "a triangle refers to a point that does not exist");
        }
    }
    if (!mesh.triangleMaterials.empty() && mesh.triangleMaterials.size() != mesh.triangles.size()) {
        OPENVDB_THROW(openvdb::ValueError, "one material index per triangle expected");
    }
    if (mesh.hasGroups()) {
        if (mesh.triangleGroups.size() != mesh.triangles.size()) {
            OPENVDB_THROW(openvdb::ValueError, "one group index per triangle expected");
        }
        for (const int32_t g : mesh.triangleGroups) {
            if (g < 0 || size_t(g) >= mesh.groups.size()) {
                OPENVDB_THROW(openvdb::ValueError, "group index " << g << " out of range");
            }
        }
    }
}

// The mesh's points in index space, refused where a coordinate leaves int32 range.
std::vector<Vec3d>
indexPoints(const TriangleMesh& mesh, double voxelSize)
{
    const double inv = 1.0 / voxelSize;
    std::vector<Vec3d> points(mesh.points.size());
    const double limit = double(1 << 30) - 16.0;
    for (size_t i = 0; i < points.size(); ++i) {
        points[i] = Vec3d(mesh.points[i]) * inv;
        for (int k = 0; k < 3; ++k) {
            if (!(std::abs(points[i][k]) < limit)) {
                std::ostringstream os;
                os << "voxel size " << voxelSize << " puts point " << i + 1
                   << " outside the index range +-2^30; use a larger voxel size";
                OPENVDB_THROW(openvdb::ValueError, os.str());
            }
        }
    }
    return points;
}

// Refuses a mesh without area, or one whose estimated surface-voxel count (area in voxels times
// the plane thickness, plus the rims) is above options.maxVoxels.
void
checkVoxelEstimate(const TriangleMesh& mesh, const std::vector<Vec3d>& points,
    const VoxelizeOptions& options, double voxelSize)
{
    double estimate = 0.0, area = 0.0;
    for (const openvdb::Vec3I& t : mesh.triangles) {
        const Vec3d& a = points[t[0]];
        const Vec3d n = (points[t[1]] - a).cross(points[t[2]] - a);
        const double len = n.length();
        if (!(len > 0.0)) continue;
        const double thick = planeThickness(n, options.separation == 26) / len;
        const double perimeter = (points[t[1]] - a).length() + (points[t[2]] - points[t[1]]).length()
            + (a - points[t[2]]).length();
        area += 0.5 * len;
        estimate += 0.5 * len * thick + 2.0 * perimeter + 1.0;
    }
    if (!(area > 0.0)) OPENVDB_THROW(openvdb::ValueError, "the mesh has no triangle of non-zero area");
    if (estimate > double(options.maxVoxels)) {
        // The count scales as 1 / voxelSize^2.
        std::ostringstream os;
        os << "about " << uint64_t(estimate) << " surface voxels at voxel size " << voxelSize
           << ", above the limit of " << options.maxVoxels << "; a voxel size of "
           << voxelSize * std::sqrt(estimate / double(options.maxVoxels)) * 1.01
           << " or more would fit";
        OPENVDB_THROW(openvdb::ValueError, os.str());
    }
}

// Whether triangle @a t has a material that emits.
bool
isEmitting(const TriangleMesh& mesh, size_t t)
{
    if (!mesh.hasMaterials()) return false;
    const int32_t m = mesh.triangleMaterials[t];
    return m >= 0 && size_t(m) < mesh.materials.size()
        && mesh.materials[size_t(m)].emission != Vec3f(0.f);
}

// The voxels that triangle @a t (a, b, c in index space) puts in the shell, each with its
// distance to the voxel centre, and for a light (@a emits) its area inside each voxel.
void
rasteriseTriangle(const Vec3d& a, const Vec3d& b, const Vec3d& c, size_t t, bool thick,
    bool emits, std::vector<Hit>& hits, std::vector<EmitHit>& emitHits)
{
    const Vec3d n = (b - a).cross(c - a);
    if (!(n.lengthSqr() > 0.0)) return;   // degenerate: covers nothing
    // Walk the voxel columns along the dominant normal axis w: in each, only the
    // voxels within the plane's thickness can meet the triangle.
    const int w = int(std::abs(n[0]) >= std::abs(n[1])
        ? (std::abs(n[0]) >= std::abs(n[2]) ? 0 : 2)
        : (std::abs(n[1]) >= std::abs(n[2]) ? 1 : 2));
    const int u = (w + 1) % 3, v = (w + 2) % 3;
    const double halfThickness = 0.5 * planeThickness(n, thick || emits);
    Coord lo, hi;
    for (int k = 0; k < 3; ++k) {
        lo[k] = int(std::ceil(std::min({a[k], b[k], c[k]}) - 0.5 - kTouch));
        hi[k] = int(std::floor(std::max({a[k], b[k], c[k]}) + 0.5 + kTouch));
    }
    const double d = n.dot(a);
    Vec3d centre;
    for (int iu = lo[u]; iu <= hi[u]; ++iu) {
        for (int iv = lo[v]; iv <= hi[v]; ++iv) {
            const double rest = d - n[u] * iu - n[v] * iv;
            double w0 = (rest - halfThickness) / n[w], w1 = (rest + halfThickness) / n[w];
            if (w0 > w1) std::swap(w0, w1);
            const int k0 = std::max(lo[w], int(std::ceil(w0 - kTouch)));
            const int k1 = std::min(hi[w], int(std::floor(w1 + kTouch)));
            for (int iw = k0; iw <= k1; ++iw) {
                centre[u] = iu;
                centre[v] = iv;
                centre[w] = iw;
                // Lights take every voxel their cube meets, whatever the shell:
                // all their area then lies in voxels (the star shell's voxels are
                // a subset, so it stays 6-separating).
                const bool meets = thick || emits
                    ? triangleMeetsVoxel(centre, a, b, c)
                    : triangleMeetsVoxelStar(centre, a, b, c);
                if (!meets) continue;
                const Coord ijk{int(centre[0]), int(centre[1]), int(centre[2])};
                hits.push_back({ijk,
                    float(squaredDistanceToTriangle(centre, a, b, c)), uint32_t(t)});
                if (emits) {
                    const double inside = areaInVoxel(centre, a, b, c);
                    if (inside > 0.0) {
                        emitHits.push_back({ijk, float(inside), uint32_t(t)});
                    }
                }
            }
        }
    }
}

// Rasterises every triangle, in parallel, into @a hits and @a emitHits (unsorted; one hit per
// triangle and voxel).
void
rasteriseMesh(const TriangleMesh& mesh, const std::vector<Vec3d>& points, bool thick,
    openvdb::util::NullInterrupter* interrupt, std::vector<Hit>& hits,
    std::vector<EmitHit>& emitHits)
{
    tbb::enumerable_thread_specific<std::vector<Hit>> hitsPerThread;
    tbb::enumerable_thread_specific<std::vector<EmitHit>> emitPerThread;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, mesh.triangles.size(), 64),
        [&](const tbb::blocked_range<size_t>& range) {
            if (openvdb::util::wasInterrupted(interrupt)) return;
            std::vector<Hit>& localHits = hitsPerThread.local();
            std::vector<EmitHit>& localEmitHits = emitPerThread.local();
            for (size_t t = range.begin(); t != range.end(); ++t) {
                const Vec3d& a = points[mesh.triangles[t][0]];
                const Vec3d& b = points[mesh.triangles[t][1]];
                const Vec3d& c = points[mesh.triangles[t][2]];
                rasteriseTriangle(a, b, c, t, thick, isEmitting(mesh, t), localHits,
                    localEmitHits);
            }
        });
    if (openvdb::util::wasInterrupted(interrupt)) throw Cancelled();

    size_t total = 0;
    for (const auto& h : hitsPerThread) total += h.size();
    hits.reserve(total);
    for (auto& h : hitsPerThread) {
        hits.insert(hits.end(), h.begin(), h.end());
        std::vector<Hit>().swap(h);
    }
    for (auto& h : emitPerThread) emitHits.insert(emitHits.end(), h.begin(), h.end());
}

// The closest triangle of each voxel: sort all hits by voxel, then distance, and keep the first.
void
keepClosestHits(std::vector<Hit>& hits)
{
    tbb::parallel_sort(hits.begin(), hits.end());
    hits.erase(std::unique(hits.begin(), hits.end(),
                   [](const Hit& x, const Hit& y) { return x.ijk == y.ijk; }),
        hits.end());
}

// Unit world-space normals per triangle; the transform is a uniform scale, so the index-space
// cross product has the world direction.
std::vector<Vec3f>
triangleNormals(const TriangleMesh& mesh, const std::vector<Vec3d>& points)
{
    std::vector<Vec3f> normals(mesh.triangles.size());
    for (size_t t = 0; t < normals.size(); ++t) {
        const Vec3d& a = points[mesh.triangles[t][0]];
        const Vec3d n = (points[mesh.triangles[t][1]] - a).cross(points[mesh.triangles[t][2]] - a);
        normals[t] = Vec3f(n.unitSafe());
    }
    return normals;
}

// The material of a triangle; null where the mesh has none or its index names none.
class MaterialLookup
{
public:
    explicit MaterialLookup(const TriangleMesh& mesh)
        : mMesh(mesh), mHasMaterials(mesh.hasMaterials()) {}

    bool hasMaterials() const { return mHasMaterials; }

    const Material* operator()(uint32_t t) const
    {
        if (!mHasMaterials) return nullptr;
        const int32_t m = mMesh.triangleMaterials[t];
        return m >= 0 && size_t(m) < mMesh.materials.size() ? &mMesh.materials[size_t(m)] : nullptr;
    }

private:
    const TriangleMesh& mMesh;
    bool mHasMaterials;
};

struct EmitVoxel
{
    Coord ijk;
    uint32_t triangle;   // the largest emitter
    double area;         // voxel faces, all emitters
    Vec3d power;         // emission times area, all emitters
    bool mixed;          // emitters of different emission
};

// The emitting voxels, from @a emitHits sorted by voxel then area. @a kept gets, per triangle:
// 1 if it holds emitting area somewhere, 2 if a voxel it is in also faces its way (the voxel's
// emitter's normal within 90 degrees of its own).
std::vector<EmitVoxel>
emittingVoxels(const std::vector<EmitHit>& emitHits, const MaterialLookup& material,
    const std::vector<Vec3f>& normals, std::vector<uint8_t>& kept)
{
    std::vector<EmitVoxel> emitters;
    for (size_t i = 0; i < emitHits.size();) {
        const EmitHit& largest = emitHits[i];
        const Vec3f& emission = material(largest.triangle)->emission;
        EmitVoxel v{largest.ijk, largest.triangle, 0.0, Vec3d(0.0), false};
        for (; i < emitHits.size() && emitHits[i].ijk == v.ijk; ++i) {
            const EmitHit& h = emitHits[i];
            const Vec3f& e = material(h.triangle)->emission;
            v.area += h.area;
            v.power += Vec3d(e) * double(h.area);
            v.mixed = v.mixed || e != emission;
            const uint8_t k = normals[h.triangle].dot(normals[v.triangle]) > 0.f ? 2 : 1;
            kept[h.triangle] = std::max(kept[h.triangle], k);
        }
        emitters.push_back(v);
    }
    return emitters;
}

Vec3f
emissionOf(const EmitVoxel& v, const MaterialLookup& material)
{
    return v.mixed ? Vec3f(v.power / v.area) : material(v.triangle)->emission;
}

// Each emitting voxel takes its normal and material from its largest emitter.
void
giveVoxelsToLights(const std::vector<EmitVoxel>& emitters, std::vector<Hit>& hits)
{
    for (size_t i = 0, k = 0; i < emitters.size(); ++i) {
        // Both sorted by voxel; every emitting voxel is a surface voxel.
        while (k < hits.size() && hits[k].ijk < emitters[i].ijk) ++k;
        if (k < hits.size() && hits[k].ijk == emitters[i].ijk) {
            hits[k].triangle = emitters[i].triangle;
        }
    }
}

// A light must not vanish unnoticed: name the emitting triangles that keep no voxel.
void
warnLostLights(const TriangleMesh& mesh, const std::vector<uint8_t>& kept,
    const MaterialLookup& material, std::vector<std::string>& warnings)
{
    auto describe = [&](size_t t) {
        std::ostringstream os;
        os << "triangle " << t + 1 << " (material '" << material(uint32_t(t))->name << "'";
        if (mesh.hasGroups()) {
            os << ", object '" << mesh.groups[size_t(mesh.triangleGroups[t])] << "'";
        }
        return os.str() + ")";
    };
    size_t lost[2] = {0, 0}, firstLost[2] = {0, 0};
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
        if (!isEmitting(mesh, t) || kept[t] == 2) continue;
        if (lost[kept[t]]++ == 0) firstLost[kept[t]] = t;
    }
    auto more = [](size_t n) {
        return n > 1 ? " (and " + std::to_string(n - 1) + " more emitting triangles)"
                     : std::string();
    };
    if (lost[0]) {
        warnings.push_back("emitting " + describe(firstLost[0])
            + " has no area: it adds no light" + more(lost[0]));
    }
    if (lost[1]) {
        warnings.push_back("emitting " + describe(firstLost[1]) + " keeps no voxel of its "
            "own: each voxel it lies in is held by a light facing another way (a two-sided "
            "light?), and its light leaves that way" + more(lost[1]));
    }
}

// An attribute grid on the normal grid's topology: value(triangle) at each surface voxel, vec3s
// if @a rgb, else float (the first channel).
template<typename ValueOf>
openvdb::GridBase::Ptr
colourGrid(const std::vector<Hit>& hits, const char* name, bool rgb, bool onlyNonZero,
    const ValueOf& value, const openvdb::math::Transform::Ptr& xform)
{
    openvdb::GridBase::Ptr out;
    if (rgb) {
        openvdb::Vec3SGrid::Ptr g = openvdb::Vec3SGrid::create(Vec3f(0.f));
        auto acc = g->getAccessor();
        for (const Hit& h : hits) {
            const Vec3f c = value(h.triangle);
            if (!onlyNonZero || c != Vec3f(0.f)) acc.setValue(h.ijk, c);
        }
        out = g;
    } else {
        openvdb::FloatGrid::Ptr g = openvdb::FloatGrid::create(0.f);
        auto acc = g->getAccessor();
        for (const Hit& h : hits) {
            const float c = value(h.triangle)[0];
            if (!onlyNonZero || c != 0.f) acc.setValue(h.ijk, c);
        }
        out = g;
    }
    out->setName(name);
    out->setTransform(xform);
    return out;
}

// `emission` and `emission_area`, only where emitting mesh lies (a voxel whose cube merely
// touches a light emits nothing).
void
addEmissionGrids(const std::vector<EmitVoxel>& emitters, bool rgbEmission,
    const MaterialLookup& material, const openvdb::math::Transform::Ptr& xform, double voxelSize,
    openvdb::GridPtrVec& grids)
{
    auto put = [&](auto grid, auto convert) {
        auto acc = grid->getAccessor();
        for (const EmitVoxel& e : emitters) acc.setValue(e.ijk, convert(emissionOf(e, material)));
        grid->setName(names::kEmission);
        grid->setTransform(xform);
        grids.push_back(grid);
    };
    if (rgbEmission) {
        put(openvdb::Vec3SGrid::create(Vec3f(0.f)), [](const Vec3f& c) { return c; });
    } else {
        put(openvdb::FloatGrid::create(0.f), [](const Vec3f& c) { return c[0]; });
    }
    openvdb::FloatGrid::Ptr area = openvdb::FloatGrid::create(0.f);
    auto acc = area->getAccessor();
    const double face = voxelSize * voxelSize;
    for (const EmitVoxel& e : emitters) acc.setValue(e.ijk, float(e.area * face));
    area->setName(names::kEmissionArea);
    area->setTransform(xform);
    grids.push_back(area);
}

// The OBJ object or group of each voxel's triangle; names in metadata, so that a file maps its
// ids back without the mesh.
openvdb::Int32Grid::Ptr
materialIdGrid(const TriangleMesh& mesh, const std::vector<Hit>& hits,
    const openvdb::math::Transform::Ptr& xform)
{
    openvdb::Int32Grid::Ptr ids = openvdb::Int32Grid::create(-1);
    auto acc = ids->getAccessor();
    for (const Hit& h : hits) acc.setValue(h.ijk, mesh.triangleGroups[h.triangle]);
    ids->setName(names::kMaterialId);
    ids->setTransform(xform);
    for (size_t i = 0; i < mesh.groups.size(); ++i) {
        ids->insertMeta(kMaterialNameMeta + std::to_string(i),
            openvdb::StringMetadata(mesh.groups[i]));
    }
    return ids;
}

// The scene's grids from the surface voxels (@a hits, each with its triangle) and the emitting
// voxels.
openvdb::GridPtrVec
surfaceGrids(const TriangleMesh& mesh, const VoxelizeOptions& options, double voxelSize,
    const std::vector<Hit>& hits, const std::vector<EmitVoxel>& emitters,
    const std::vector<Vec3f>& normals, const MaterialLookup& material,
    openvdb::util::NullInterrupter* interrupt)
{
    // Materials actually used decide the grid types: RGB only where some colour is not grey.
    bool rgbAlbedo = false, rgbEmission = false, rgbSpecular = false;
    for (const Hit& h : hits) {
        if (const Material* m = material(h.triangle)) {
            rgbAlbedo = rgbAlbedo || !isGrey(m->albedo);
            rgbSpecular = rgbSpecular || !isGrey(m->specular);
        }
    }
    for (const EmitVoxel& e : emitters) {
        rgbEmission = rgbEmission || !isGrey(emissionOf(e, material));
    }

    openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(voxelSize);
    openvdb::Vec3SGrid::Ptr normalGrid = openvdb::Vec3SGrid::create(Vec3f(0.f));
    normalGrid->setName(names::kNormal);
    normalGrid->setTransform(xform);
    normalGrid->setVectorType(openvdb::VEC_COVARIANT_NORMALIZE);
    {
        auto acc = normalGrid->getAccessor();
        for (const Hit& h : hits) acc.setValue(h.ijk, normals[h.triangle]);
    }
    openvdb::GridPtrVec grids{normalGrid};

    // Attribute grids share the normal grid's topology (emission: only the emitting voxels, as
    // an attribute grid's inactive background is its value elsewhere).
    // Glossy materials reflecting more than all (Kd + Ks > 1) are scaled to 1.
    const bool hasMaterials = material.hasMaterials();
    const bool glossy = hasMaterials && options.specular && mesh.hasSpecular();
    auto conserved = [&](const Material& m) {
        return glossy ? 1.f / std::max(1.f, m.reflectance()) : 1.f;
    };
    if (hasMaterials) {
        grids.push_back(colourGrid(hits, names::kAlbedo, rgbAlbedo, false, [&](uint32_t t) {
            const Material* m = material(t);
            return m ? m->albedo * conserved(*m) : Vec3f(options.defaultAlbedo);
        }, xform));
    }
    if (glossy) {
        grids.push_back(colourGrid(hits, names::kSpecular, rgbSpecular, false, [&](uint32_t t) {
            const Material* m = material(t);
            return m ? m->specular * conserved(*m) : Vec3f(0.f);
        }, xform));
        grids.push_back(colourGrid(hits, names::kRoughness, false, false, [&](uint32_t t) {
            const Material* m = material(t);
            return Vec3f(m ? m->roughness : 0.5f);
        }, xform));
    }
    if (!emitters.empty()) {
        addEmissionGrids(emitters, rgbEmission, material, xform, voxelSize, grids);
    }
    if (mesh.hasGroups()) grids.push_back(materialIdGrid(mesh, hits, xform));
    if (options.keepSdf) {
        if (interrupt) interrupt->start("level set");
        std::vector<Vec3f> worldPoints(mesh.points.begin(), mesh.points.end());
        openvdb::FloatGrid::Ptr sdf = openvdb::tools::meshToLevelSet<openvdb::FloatGrid>(
            *xform, worldPoints, mesh.triangles, 3.f);
        sdf->setName("surface");
        grids.push_back(sdf);
        if (interrupt) interrupt->end();
    }
    return grids;
}

} // namespace

openvdb::GridPtrVec
voxelizeMesh(const TriangleMesh& mesh, const VoxelizeOptions& options,
    openvdb::util::NullInterrupter* interrupt, std::vector<std::string>* warnings)
{
    checkVoxelizeInput(mesh, options);
    const double voxelSize = voxelizeVoxelSize(mesh, options);

    // Index-space corners, and the guards that must pass before anything is allocated: int32
    // coordinates, and a voxel-count estimate (area in voxels times the plane thickness ||n||_1
    // for 26, ||n||_inf for 6, plus the rims).
    const std::vector<Vec3d> points = indexPoints(mesh, voxelSize);
    checkVoxelEstimate(mesh, points, options, voxelSize);

    if (interrupt) interrupt->start("voxelizing the mesh");
    std::vector<Hit> hits;
    std::vector<EmitHit> emitHits;
    rasteriseMesh(mesh, points, options.separation == 26, interrupt, hits, emitHits);
    keepClosestHits(hits);
    if (openvdb::util::wasInterrupted(interrupt)) throw Cancelled();

    const std::vector<Vec3f> normals = triangleNormals(mesh, points);
    const MaterialLookup material(mesh);

    // Emission takes precedence within a voxel: each voxel holding emitting area emits the mean
    // emission of that area (so its power, emission times emission_area, is the mesh's however
    // many lights share it) and takes normal and material from the emitter holding most of it,
    // never from a wall closer to its centre: a light 1 cm under a ceiling stays a light at any
    // resolution, and the voxelised lights' power is the mesh's.
    std::sort(emitHits.begin(), emitHits.end());
    std::vector<uint8_t> kept(mesh.triangles.size(), 0);
    const std::vector<EmitVoxel> emitters = emittingVoxels(emitHits, material, normals, kept);
    giveVoxelsToLights(emitters, hits);
    if (warnings) warnLostLights(mesh, kept, material, *warnings);

    openvdb::GridPtrVec grids =
        surfaceGrids(mesh, options, voxelSize, hits, emitters, normals, material, interrupt);
    if (interrupt) interrupt->end();
    return grids;
}

} // namespace vdbrad
