#include "vdbrad/surface/DirectLight.h"

#include "vdbrad/core/Constants.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/core/SampleHash.h"
#include "vdbrad/core/VoxelMarch.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/scene/SurfacePlanes.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>

namespace vdbrad {

namespace {

using openvdb::Vec3d;
// A patch farther than this many of its radii is a point source: for a disk seen head-on the
// point value a^2 / h^2 overestimates a^2 / (h^2 + a^2) by (a / h)^2, here 1e-3.
constexpr double kFarRadii = 32.0;
// Where a voxel's first rays disagree, it is cast this many times as many
// (docs/journal/2026-12-03-exact-direct-light.md).
constexpr size_t kPenumbra = 4;
// A receiver this close to a patch's plane (voxels) is on it: it sees none of it.
constexpr double kOnPlane = 1e-9;

// Lambert's contour sum of one closed loop (signed; its orientation gives the sign).
double
contour(const Vec3d& p, const Vec3d& n, const Vec3d* v, size_t m)
{
    double sum = 0.0;
    for (size_t i = 0; i < m; ++i) {
        const Vec3d a = v[i] - p, b = v[i + 1 == m ? 0 : i + 1] - p;
        const Vec3d c = a.cross(b);
        const double length = c.length();
        if (!(length > 0.0)) continue;   // the edge points at p: it subtends nothing
        sum += std::atan2(length, a.dot(b)) * n.dot(c) / length;
    }
    return sum;
}

// Does the ray from @a p (off voxel @a self) to @a y on patch @a g arrive? Voxels stop it by
// the surface rule (SurfacePlanes::stops). g = kNone: @a y is out of the box (the sky).
bool
arrives(const Emitters& emitters, const SurfacePlanes& planes, VoxelIndex::Accessor& acc,
    const openvdb::CoordBBox& box, uint32_t self, const Vec3d& p, const Vec3d& y, int32_t g)
{
    const Vec3d d = y - p;
    bool arrived = true;
    marchVoxels(acc, box, p + Vec3d(0.5), d, 0.0, 1.0, [&](int32_t index, double tIn,
            double tOut) {
        if (uint32_t(index) == self) return true;
        if (g != Emitters::kNone && emitters.patchOf(size_t(index)) == g) return false;
        // The march's accessor: its lookups stay exact whatever the rule cached last.
        if (planes.stops(size_t(index), p, d, tIn, tOut, acc)) {
            arrived = false;
            return false;
        }
        return true;
    });
    return arrived;
}

// The patches @a p (normal @a nx) faces: those in room @a room but its own patch @a own whose
// form factor and weight (form factor times mean exitance) are positive, into the front list of
// @a ws with their form factors and weights. Returns the weights' total.
inline double
gatherFront(const std::vector<EmitterPatch>& patches, const std::vector<uint32_t>& patchRegion,
    int32_t own, uint32_t room, const Vec3d& p, const Vec3d& nx,
    DirectLightSampler::Workspace& ws)
{
    double total = 0.0;
    for (size_t g = 0; g < patches.size(); ++g) {
        if (int32_t(g) == own || patchRegion[g] != room) continue;
        const double f = patchFormFactor(p, nx, patches[g]);
        ++ws.factors;
        if (!(f > 0.0)) continue;
        const Vec3d& m = patches[g].exitance;
        const double w = f * (m[0] + m[1] + m[2]) / 3.0;
        if (!(w > 0.0)) continue;
        ws.factor[g] = f;
        ws.weight[g] = w;
        total += w;
        ws.front.push_back(uint32_t(g));
    }
    return total;
}

// Where the light at @a p comes from, into ws.incident: each front patch's light over its
// arrived samples (ws.arrivals, in front order) by their weights, or from its centre if none
// arrived; a patch no sample weighed on (share -1) takes @a overall.
inline void
dealIncident(const std::vector<EmitterPatch>& patches, const Vec3d& p, double overall,
    DirectLightSampler::Workspace& ws)
{
    ws.incident->clear();
    size_t e = 0;
    for (size_t q = 0; q < ws.front.size(); ++q) {
        const size_t g = ws.front[q];
        const double v = ws.shares[q] >= 0.0 ? ws.shares[q] : overall;
        const Vec3d light = patches[g].exitance * (ws.factor[g] * v);
        const size_t first = e;
        double total = 0.0;
        for (; e < ws.arrivals.size() && std::get<0>(ws.arrivals[e]) == q; ++e) {
            total += std::get<2>(ws.arrivals[e]);
        }
        if (!(v > 0.0)) continue;
        if (total > 0.0) {
            for (size_t k = first; k < e; ++k) {
                ws.incident->emplace_back(std::get<1>(ws.arrivals[k]),
                    light * (std::get<2>(ws.arrivals[k]) / total));
            }
        } else {
            ws.incident->emplace_back((patches[g].centre - p).unit(), light);
        }
    }
}

} // namespace

bool
usesExactDirect(DirectMode mode, const Scene& scene, bool sun)
{
    if (mode == DirectMode::Sweep) return false;
    if (sun) return true;
    if (!scene.hasEmission()) return false;
    if (mode == DirectMode::Exact) return true;
    // Counted before any patch is built: a furnace (all emitters) builds none.
    size_t emitting = 0;
    for (size_t i = 0; i < scene.size(); ++i) {
        emitting += Emitters::emits(scene.emission().rgb(i)) ? 1 : 0;
    }
    return emitting * 2 <= scene.size();
}

double
polygonFormFactor(const Vec3d& p, const Vec3d& n,
    const std::vector<std::vector<Vec3d>>& loops)
{
    double sum = 0.0;
    std::vector<Vec3d> clipped;
    for (const std::vector<Vec3d>& loop : loops) {
        const size_t m = loop.size();
        bool front = false, back = false;
        for (const Vec3d& v : loop) {
            const double s = n.dot(v - p);
            front |= s > 0.0;
            back |= s < 0.0;
        }
        if (!front) continue;
        if (!back) {
            sum += contour(p, n, loop.data(), m);
            continue;
        }
        // Sutherland-Hodgman against x's tangent plane. A concave loop may come out as pieces
        // joined by back-and-forth runs along the plane; those cancel in the contour sum.
        clipped.clear();
        for (size_t i = 0; i < m; ++i) {
            const Vec3d& a = loop[i];
            const Vec3d& b = loop[i + 1 == m ? 0 : i + 1];
            const double sa = n.dot(a - p), sb = n.dot(b - p);
            if (sa >= 0.0) clipped.push_back(a);
            if ((sa >= 0.0) != (sb >= 0.0)) clipped.push_back(a + (b - a) * (sa / (sa - sb)));
        }
        if (clipped.size() >= 3) sum += contour(p, n, clipped.data(), clipped.size());
    }
    return std::abs(sum) / (2.0 * kPi);
}

double
patchFormFactor(const Vec3d& p, const Vec3d& n, const EmitterPatch& patch)
{
    const double height = patch.normal.dot(p) - patch.offset;
    if (!(height > kOnPlane)) return 0.0;
    const Vec3d toCentre = patch.centre - p;
    const double r2 = toCentre.lengthSqr();
    if (r2 > kFarRadii * kFarRadii * patch.radius * patch.radius) {
        const double cosX = n.dot(toCentre), cosG = -patch.normal.dot(toCentre);
        if (cosX <= 0.0 || cosG <= 0.0) return 0.0;
        return patch.area * cosX * cosG / (kPi * r2 * r2);
    }
    return polygonFormFactor(p, n, patch.loops);
}

DirectLightSampler::DirectLightSampler(const Scene& scene, const Emitters& emitters,
    const DirectLightOptions& options, const std::vector<uint32_t>* regions)
    : mScene(scene), mEmitters(emitters), mOptions(options), mRegions(regions)
    , mBox(scene.voxels().bbox())
    , mPlanes(scene)
{
    if (options.samples < 1) {
        OPENVDB_THROW(openvdb::ValueError, "direct-light samples must be >= 1, got "
            << options.samples);
    }
    // The room each patch faces: that of its first voxel (a flat patch faces one room).
    const std::vector<EmitterPatch>& patches = emitters.patches();
    mPatchRegion.assign(patches.size(), 0);
    if (regions) {
        std::vector<char> known(patches.size(), 0);
        for (size_t i = 0; i < scene.size(); ++i) {
            const int32_t g = emitters.patchOf(i);
            if (g == Emitters::kNone || known[size_t(g)]) continue;
            known[size_t(g)] = 1;
            mPatchRegion[size_t(g)] = (*regions)[i];
        }
    }
    if (const auto& sun = options.sun) {
        mToSun = sunDirection(sun->zenith, sun->azimuth, sun->up, scene.transform()).unit();
        // Any unit vector off the beam's axis gives the two axes across it.
        const Vec3d off = std::abs(mToSun[0]) < 0.9 ? Vec3d(1, 0, 0) : Vec3d(0, 1, 0);
        mAcross1 = mToSun.cross(off).unit();
        mAcross2 = mToSun.cross(mAcross1);
        mSunRadius = 0.5 * sun->diameter * kPi / 180.0;
        mRayLength = 2.0 * (mBox.dim().asVec3d().length() + 2.0);
    }
}

DirectLightSampler::Workspace::Workspace(const DirectLightSampler& sampler)
    : acc(sampler.mScene.voxels().tree())
{
}

openvdb::Vec3d
DirectLightSampler::at(const Vec3d& p, const Vec3d& nx, size_t self, uint64_t h,
    Workspace& ws) const
{
    Vec3d sum = emittersAt(p, nx, self, h, ws);
    if (mOptions.sun) sum += sunAt(p, nx, self, h, ws);
    return sum;
}

// The sun's share: E max(0, n . s) times the share of rays to points of its disk that leave the
// box; where they disagree (a penumbra), again with kPenumbra times the rays.
openvdb::Vec3d
DirectLightSampler::sunAt(const Vec3d& p, const Vec3d& nx, size_t self, uint64_t h,
    Workspace& ws) const
{
    const double cosine = nx.dot(mToSun);
    const Vec3d& E = mOptions.sun->irradiance;
    if (!(cosine > 0.0) || !(E[0] > 0.0 || E[1] > 0.0 || E[2] > 0.0)) return Vec3d(0.0);
    const Vec3d origin = mPlanes.rayOrigin(self, p);
    // Points of the disk from an R2 sequence shifted per voxel (its own stream of the hash).
    const double shiftU = unitHash(mixHash(h + 0x5157)), shiftV = unitHash(mixHash(h + 0x5158));
    auto share = [&](size_t count, bool& mixed) {
        size_t seen = 0;
        for (size_t j = 0; j < count; ++j) {
            const double u = std::fmod(shiftU + 0.7548776662466927 * double(j), 1.0);
            const double v = std::fmod(shiftV + 0.5698402909980532 * double(j), 1.0);
            const double r = mSunRadius * std::sqrt(u), phi = 2.0 * kPi * v;
            const Vec3d d = mToSun + mAcross1 * (r * std::cos(phi)) + mAcross2 * (r * std::sin(phi));
            ++ws.rays;
            if (arrives(mEmitters, mPlanes, ws.acc, mBox, uint32_t(self), origin,
                    origin + d.unit() * mRayLength, Emitters::kNone)) {
                ++seen;
            }
        }
        mixed = seen > 0 && seen < count;
        return double(seen) / double(count);
    };
    const size_t S = size_t(mOptions.samples);
    bool mixed = false;
    double visible = share(S, mixed);
    if (mixed) visible = share(kPenumbra * S, mixed);
    const Vec3d irradiance = E * (cosine * visible);
    if (ws.incident && visible > 0.0) ws.incident->emplace_back(mToSun, irradiance);
    return irradiance;
}

// The emitters' share (the file comment).
openvdb::Vec3d
DirectLightSampler::emittersAt(const Vec3d& p, const Vec3d& nx, size_t self, uint64_t h,
    Workspace& ws) const
{
    const std::vector<EmitterPatch>& patches = mEmitters.patches();
    const size_t S = size_t(mOptions.samples);
    const int32_t own = mEmitters.patchOf(self);
    ws.weight.resize(patches.size());
    ws.factor.resize(patches.size());
    ws.front.clear();
    // A voxel no lamp reaches returns before estimating: it must not pass on the arrivals
    // of the voxel before it.
    if (ws.incident) ws.incident->clear();
    const uint32_t room = mRegions ? (*mRegions)[self] : 0;
    const double total = gatherFront(patches, mPatchRegion, own, room, p, nx, ws);
    if (!(total > 0.0)) return Vec3d(0.0);

    // Stratified points on the patches, in proportion to their weights: sample j at
    // u = (j + xi) / count along the patches' cumulative weight, so consecutive samples
    // stay on one patch and each patch's visible share is a ratio of its own samples.
    // Within a patch, the k-th point is the k-th of an R2 sequence (Roberts' additive
    // recurrence, well spread for any k) over its columns' bounding rectangle, shifted
    // per voxel; a point off the patch weighs nothing. @a mixed: some ray arrived and
    // some did not (a penumbra).
    const double shiftU = unitHash(mixHash(h + 1)), shiftV = unitHash(mixHash(h + 2));
    const Vec3d origin = mPlanes.rayOrigin(self, p);
    auto estimate = [&](size_t count, bool& mixed) {
        double allA = 0.0, allAV = 0.0;
        size_t at = 0, k = 0;
        double below = 0.0;         // cumulative weight before patch front[at]
        double a = 0.0, av = 0.0;   // patch front[at]: sample weights, those seen
        bool anySeen = false, anyHidden = false;
        // Per front patch, its seen share of the integrand; -1: no sample weighs
        // anything there (none reached it, or all fell off it or behind x).
        std::vector<double>& shares = ws.shares;
        shares.assign(ws.front.size(), -1.0);
        ws.arrivals.clear();
        for (size_t j = 0; j < count; ++j) {
            const double u = (double(j) + unitHash(mixHash(h + 3 * j + 3)))
                / double(count) * total;
            while (at + 1 < ws.front.size() && u >= below + ws.weight[ws.front[at]]) {
                if (a > 0.0) shares[at] = av / a;
                below += ws.weight[ws.front[at]];
                ++at;
                k = 0;
                a = av = 0.0;
            }
            const int32_t g = int32_t(ws.front[at]);
            const EmitterPatch& patch = patches[size_t(g)];
            const double su = std::fmod(shiftU + 0.7548776662466927 * double(k), 1.0);
            const double sv = std::fmod(shiftV + 0.5698402909980532 * double(k), 1.0);
            ++k;
            const double pu = double(patch.lower[0]) - 0.5
                + su * (double(patch.upper[0]) - patch.lower[0] + 1);
            const double pv = double(patch.lower[1]) - 0.5
                + sv * (double(patch.upper[1]) - patch.lower[1] + 1);
            if (!patch.covers(pu, pv)) continue;
            const Vec3d y = patch.lift(pu, pv);
            const Vec3d d = y - p;
            const double r2 = d.lengthSqr();
            const double cosCos =
                std::max(0.0, nx.dot(d)) * std::max(0.0, -patch.normal.dot(d));
            // The integrand over its mean: an unbiased estimate of 1 where all is seen.
            const double weight = r2 > 0.0
                ? cosCos / (r2 * r2) * patch.area / (kPi * ws.factor[size_t(g)]) : 0.0;
            if (!(weight > 0.0)) continue;
            ++ws.rays;
            a += weight;
            allA += weight;
            if (arrives(mEmitters, mPlanes, ws.acc, mBox, uint32_t(self), origin, y, g)) {
                av += weight;
                allAV += weight;
                anySeen = true;
                if (ws.incident) ws.arrivals.emplace_back(uint32_t(at), d / std::sqrt(r2), weight);
            } else {
                anyHidden = true;
            }
        }
        if (a > 0.0) shares[at] = av / a;
        mixed = anySeen && anyHidden;
        // A patch no sample weighs on takes the share of all samples.
        const double overall = allA > 0.0 ? allAV / allA : 1.0;
        Vec3d sum(0.0);
        for (size_t q = 0; q < ws.front.size(); ++q) {
            const size_t g = ws.front[q];
            const double v = shares[q] >= 0.0 ? shares[q] : overall;
            sum += patches[g].exitance * (ws.factor[g] * v);
        }
        if (ws.incident) dealIncident(patches, p, overall, ws);
        return sum;
    };
    bool mixed = false;
    Vec3d sum = estimate(S, mixed);
    // A penumbra: again with kPenumbra times the rays (the only place rays disagree).
    if (mixed) sum = estimate(kPenumbra * S, mixed);
    return sum;
}

DirectIrradiance
directIrradiance(const Scene& scene, const Emitters& emitters, const DirectLightOptions& options,
    const std::vector<uint32_t>* regions, openvdb::util::NullInterrupter* interrupt,
    const IncidentSink* incident)
{
    const DirectLightSampler sampler(scene, emitters, options, regions);
    const auto t0 = std::chrono::steady_clock::now();
    const size_t n = scene.size();
    DirectIrradiance out;
    out.irradiance.assign(n, openvdb::Vec3f(0.f));
    if (emitters.patches().empty() && !options.sun) return out;
    std::atomic<uint64_t> rays{0}, factors{0};
    std::atomic<size_t> done{0};
    std::atomic<bool> cancelled{false};

    // Under MPI the ranks share the voxels out in blocks (Distribution.h): each voxel's value
    // depends on itself alone (its own sample seed), so the sum over ranks of values computed
    // by one rank and zeros elsewhere is the serial result, bit for bit. The incident sink sees
    // only this rank's voxels: its owner combines what it gathered.
    const Distribution alone;
    const Distribution& ranks = Distribution::orAlone(options.ranks, alone);
    constexpr size_t kBlock = 1024;
    std::vector<size_t> mine;
    for (size_t b = 0; b * kBlock < n; ++b) {
        if (ranks.ownsBlock(b)) mine.push_back(b);
    }
    const size_t total = std::max<size_t>(mine.size() * kBlock, 1);
    using Range = tbb::blocked_range<size_t>;
    tbb::parallel_for(Range(0, mine.size() * kBlock, 64), [&](const Range& r) {
        if (cancelled) return;
        DirectLightSampler::Workspace ws(sampler);
        std::vector<std::pair<Vec3d, Vec3d>> pairs;
        for (size_t k = r.begin(); k != r.end(); ++k) {
            const size_t i = mine[k / kBlock] * kBlock + k % kBlock;
            if (i >= n) continue;
            const bool wanted = incident && incident->wants(i);
            ws.incident = wanted ? &pairs : nullptr;
            out.irradiance[i] = openvdb::Vec3f(sampler.at(scene.voxels().coord(i).asVec3d(),
                Vec3d(scene.normal(i)), i, mixHash(options.seed ^ mixHash(uint64_t(i))), ws));
            if (wanted) incident->take(i, pairs);
        }
        rays += ws.rays;
        factors += ws.factors;
        const size_t d = done += r.size();
        if (interrupt && interrupt->wasInterrupted(int(100 * d / total))) cancelled = true;
    });
    if (cancelled) throw Cancelled("direct light");
    out.rays = rays;
    out.factors = factors;
    if (ranks.distributed()) {
        ranks.combine(&out.irradiance[0][0], 3 * n);
        out.rays = uint64_t(ranks.sum(double(out.rays)));
        out.factors = uint64_t(ranks.sum(double(out.factors)));
    }
    out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return out;
}

} // namespace vdbrad
