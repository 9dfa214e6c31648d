#include "vdbrad/scene/Emitters.h"

#include <algorithm>
#include <array>
#include <climits>
#include <cmath>
#include <cstdint>
#include <deque>
#include <map>

namespace vdbrad {

namespace {

// Patches join voxels whose normals agree this closely (componentwise, to the patch's first
// voxel): a flat light from a mesh or a level set's plane, not a curved lamp's neighbours.
constexpr double kNormalTolerance = 1e-4;

bool
byColumn(const openvdb::Vec2i& a, const openvdb::Vec2i& b)
{
    return a[0] < b[0] || (a[0] == b[0] && a[1] < b[1]);
}

// A corner of the outline in doubled coordinates (squares' corners are odd): 64 bits, as
// doubling an int32 coordinate may not fit in 32.
using Corner = std::array<int64_t, 2>;

// The outline of a set of unit squares (sorted columns) as closed loops of doubled-integer
// corners, counter-clockwise around the squares, collinear edges merged.
std::vector<std::vector<Corner>>
outline(const std::vector<openvdb::Vec2i>& columns)
{
    using openvdb::Vec2i;
    auto has = [&](int64_t i, int64_t j) {
        if (i < INT32_MIN || i > INT32_MAX || j < INT32_MIN || j > INT32_MAX) return false;
        return std::binary_search(columns.begin(), columns.end(), Vec2i(int(i), int(j)),
            byColumn);
    };
    // A square's side is on the outline iff the square across it is missing.
    struct Edge { Corner from, to; bool used; };
    std::vector<Edge> edges;
    for (const Vec2i& c : columns) {
        const int64_t i = c[0], j = c[1];
        const int64_t x0 = 2 * i - 1, x1 = 2 * i + 1, y0 = 2 * j - 1, y1 = 2 * j + 1;
        if (!has(i, j - 1)) edges.push_back({Corner{x0, y0}, Corner{x1, y0}, false});
        if (!has(i + 1, j)) edges.push_back({Corner{x1, y0}, Corner{x1, y1}, false});
        if (!has(i, j + 1)) edges.push_back({Corner{x1, y1}, Corner{x0, y1}, false});
        if (!has(i - 1, j)) edges.push_back({Corner{x0, y1}, Corner{x0, y0}, false});
    }
    std::map<Corner, std::vector<size_t>> leaving;
    for (size_t e = 0; e < edges.size(); ++e) leaving[edges[e].from].push_back(e);
    // Every corner has as many outline edges in as out, so a walk from any unused edge comes
    // back to its start; where two loops touch (diagonal squares) either way round is a loop.
    std::vector<std::vector<Corner>> loops;
    for (size_t first = 0; first < edges.size(); ++first) {
        if (edges[first].used) continue;
        std::vector<Corner> loop;
        size_t e = first;
        while (true) {
            edges[e].used = true;
            loop.push_back(edges[e].from);
            const Corner at = edges[e].to;
            if (at == edges[first].from) break;
            size_t next = edges.size();
            for (const size_t candidate : leaving[at]) {
                if (!edges[candidate].used) { next = candidate; break; }
            }
            if (next == edges.size()) break;   // cannot happen for a set of squares
            e = next;
        }
        // Merge straight runs: drop corners where the direction does not change (the steps
        // run along the axes, so their signs decide).
        auto sign = [](int64_t d) { return int64_t(d > 0) - int64_t(d < 0); };
        std::vector<Corner> merged;
        const size_t m = loop.size();
        for (size_t i = 0; i < m; ++i) {
            const Corner& a = loop[(i + m - 1) % m];
            const Corner& b = loop[i];
            const Corner& c = loop[(i + 1) % m];
            const int64_t turn = sign(b[0] - a[0]) * sign(c[1] - b[1])
                - sign(b[1] - a[1]) * sign(c[0] - b[0]);
            if (turn != 0) merged.push_back(b);
        }
        if (merged.size() >= 3) loops.push_back(std::move(merged));
    }
    return loops;
}

} // namespace

openvdb::Vec3d
EmitterPatch::lift(double u, double v) const
{
    const int a = (axis + 1) % 3, b = (axis + 2) % 3;
    const int first = std::min(a, b), second = std::max(a, b);
    openvdb::Vec3d q;
    q[first] = u;
    q[second] = v;
    q[axis] = (offset - normal[first] * u - normal[second] * v) / normal[axis];
    return q;
}

bool
EmitterPatch::covers(double u, double v) const
{
    const openvdb::Vec2i c(int(std::floor(u + 0.5)), int(std::floor(v + 0.5)));
    if (c[0] < lower[0] || c[0] > upper[0] || c[1] < lower[1] || c[1] > upper[1]) return false;
    // A full rectangle needs no search.
    const double box = (double(upper[0]) - lower[0] + 1) * (double(upper[1]) - lower[1] + 1);
    if (double(columns.size()) == box) return true;
    return std::binary_search(columns.begin(), columns.end(), c, byColumn);
}

Emitters::Emitters(const Scene& scene)
{
    using openvdb::Coord;
    using openvdb::Vec3d;
    const size_t n = scene.size();
    if (scene.emission().isZero()) return;
    const VoxelIndex& voxels = scene.voxels();
    mPatchOf.assign(n, kNone);
    VoxelIndex::Accessor acc(voxels.tree());
    std::deque<size_t> queue;
    for (size_t seed = 0; seed < n; ++seed) {
        const openvdb::Vec3f e = scene.emission().rgb(seed);
        if (mPatchOf[seed] != kNone || !emits(e)) continue;
        const int32_t id = int32_t(mPatches.size());
        const openvdb::Vec3f ns = scene.normal(seed);
        std::vector<size_t> members{seed};
        mPatchOf[seed] = id;
        queue.push_back(seed);
        while (!queue.empty()) {
            const Coord c = voxels.coord(queue.front());
            queue.pop_front();
            for (int dx = -1; dx <= 1; ++dx) for (int dy = -1; dy <= 1; ++dy) {
                for (int dz = -1; dz <= 1; ++dz) {
                    const int32_t j = acc.getValue(c.offsetBy(dx, dy, dz));
                    if (j < 0 || mPatchOf[size_t(j)] != kNone) continue;
                    if (scene.emission().rgb(size_t(j)) != e) continue;
                    const openvdb::Vec3f d = scene.normal(size_t(j)) - ns;
                    if (std::max({std::abs(d[0]), std::abs(d[1]), std::abs(d[2])})
                        > kNormalTolerance) {
                        continue;
                    }
                    mPatchOf[size_t(j)] = id;
                    members.push_back(size_t(j));
                    queue.push_back(size_t(j));
                }
            }
        }
        std::sort(members.begin(), members.end());   // the offset's sum in a fixed order
        mVoxels += members.size();

        EmitterPatch p;
        p.normal = Vec3d(ns).unitSafe();
        p.axis = 0;
        for (int k = 1; k < 3; ++k) {
            if (std::abs(p.normal[k]) > std::abs(p.normal[p.axis])) p.axis = k;
        }
        p.exitance = Vec3d(e);
        const int a = std::min((p.axis + 1) % 3, (p.axis + 2) % 3);
        const int b = std::max((p.axis + 1) % 3, (p.axis + 2) % 3);
        double offset = 0.0;
        for (const size_t m : members) {
            const Coord c = voxels.coord(m);
            offset += p.normal.dot(c.asVec3d());
            p.columns.emplace_back(c[a], c[b]);
        }
        p.offset = offset / double(members.size());
        std::sort(p.columns.begin(), p.columns.end(), byColumn);
        p.columns.erase(std::unique(p.columns.begin(), p.columns.end()), p.columns.end());
        p.lower = p.upper = p.columns.front();
        for (const openvdb::Vec2i& c : p.columns) {
            for (int k = 0; k < 2; ++k) {
                p.lower[k] = std::min(p.lower[k], c[k]);
                p.upper[k] = std::max(p.upper[k], c[k]);
            }
        }
        p.area = double(p.columns.size()) / std::abs(p.normal[p.axis]);
        if (scene.hasEmissionArea()) {
            // The mesh's emitting area, spread evenly over the patch: its power is the mesh's,
            // while its outline is the voxels' (a partly covered rim voxel counts in full).
            double carried = 0.0;
            for (const size_t m : members) carried += scene.emissionArea().grey(m);
            p.exitance *= carried / p.area;
        }
        openvdb::BBoxd box;
        for (const auto& loop : outline(p.columns)) {
            std::vector<Vec3d> lifted;
            for (const Corner& v : loop) {
                lifted.push_back(p.lift(0.5 * double(v[0]), 0.5 * double(v[1])));
                box.expand(lifted.back());
            }
            p.loops.push_back(std::move(lifted));
        }
        p.centre = box.getCenter();
        for (const auto& loop : p.loops) {
            for (const Vec3d& v : loop) p.radius = std::max(p.radius, (v - p.centre).length());
        }
        mPatches.push_back(std::move(p));
    }
}

Attribute
Emitters::exitance(const Scene& scene) const
{
    if (!scene.hasEmissionArea()) return scene.emission();
    const size_t n = scene.size();
    // Voxels of one patch share its exitance; a voxel of no patch emits nothing (emits()).
    if (scene.emission().isRgb()) {
        std::vector<openvdb::Vec3f> e(n, openvdb::Vec3f(0.f));
        for (size_t i = 0; i < n; ++i) {
            const int32_t g = patchOf(i);
            if (g != kNone) e[i] = openvdb::Vec3f(mPatches[size_t(g)].exitance);
        }
        return Attribute::fromRgb(std::move(e));
    }
    std::vector<float> e(n, 0.f);
    for (size_t i = 0; i < n; ++i) {
        const int32_t g = patchOf(i);
        if (g != kNone) e[i] = float(mPatches[size_t(g)].exitance[0]);
    }
    return Attribute::fromGrey(std::move(e));
}

double
Emitters::power() const
{
    double sum = 0.0;
    for (const EmitterPatch& p : mPatches) {
        const openvdb::Vec3d w = p.power();
        sum += (w[0] + w[1] + w[2]) / 3.0;
    }
    return sum;
}

size_t
Emitters::edges() const
{
    size_t sum = 0;
    for (const EmitterPatch& p : mPatches) {
        for (const auto& loop : p.loops) sum += loop.size();
    }
    return sum;
}

} // namespace vdbrad
