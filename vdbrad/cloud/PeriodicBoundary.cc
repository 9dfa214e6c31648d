#include "vdbrad/cloud/PeriodicBoundary.h"
#include "vdbrad/core/Constants.h"

#include <algorithm>
#include <cmath>

namespace vdbrad {

namespace {

using openvdb::Coord;
using openvdb::Vec3d;


// The face a ray through index point p along unit t crosses first, over the box [lo, hi]:
// 2 * axis + (0: low, 1: high), or -1 if it is the top or bottom; and the up coordinate of the
// crossing.
int
crossedSide(const Vec3d& p, const Vec3d& t, const Vec3d& lo, const Vec3d& hi, int up,
    double& height)
{
    double best = 1e300;
    int face = -1;
    for (int k = 0; k < 3; ++k) {
        if (t[k] == 0.0) continue;
        const double bound = t[k] > 0.0 ? hi[k] : lo[k];
        const double s = (bound - p[k]) / t[k];
        if (s < best) {
            best = s;
            face = 2 * k + (t[k] > 0.0 ? 1 : 0);
        }
    }
    height = p[up] + best * t[up];
    return face / 2 == up ? -1 : face;
}

// The neighbour of c on its line, one step along +sigma (dir 1) or -sigma (dir -1): a naive line
// has one voxel per major coordinate, so it is one of four candidates. Returns false where the
// line has no voxel there (a centred partition's central line at its bound).
bool
stepAlong(const LinePartition& part, const Coord& sigma, const Coord& c, int dir, Coord& out)
{
    const int major = part.majorAxis();
    const LineKey key = part.key(c);
    Coord base = c;
    base[major] += dir * (sigma[major] > 0 ? 1 : -1);
    int minor[2], n = 0;
    for (int k = 0; k < 3; ++k) if (k != major) minor[n++] = k;
    for (int d1 = 0; d1 < 2; ++d1) {
        if (d1 && sigma[minor[0]] == 0) continue;
        for (int d2 = 0; d2 < 2; ++d2) {
            if (d2 && sigma[minor[1]] == 0) continue;
            Coord q = base;
            q[minor[0]] += dir * d1 * (sigma[minor[0]] > 0 ? 1 : -1);
            q[minor[1]] += dir * d2 * (sigma[minor[1]] > 0 ? 1 : -1);
            if (part.key(q) == key) { out = q; return true; }
        }
    }
    return false;
}

} // namespace

PeriodicBoundary::PeriodicBoundary(const openvdb::CoordBBox& box, int up,
    const SweepSchedule& schedule, const FlatAxes& flat)
    : mLo(box.min().asVec3d() - Vec3d(0.5))
    , mHi(box.max().asVec3d() + Vec3d(0.5))
    , mMin(box.min())
    , mMax(box.max())
    , mUp(up)
    , mLayers(box.max()[up] - box.min()[up] + 1)
    , mLayer0(box.min()[up])
    , mFlat(flat)
{
    const DirectionSet& dirs = schedule.directions();
    mEnterCount.assign(dirs.size() * sliceSize(), 0);
    // Each direction counts into its own slice: no races.
    struct Started { bool started = false; };
    SweepSchedule::PerThread<LineSweep::Lanes<Started>> lanes;
    const SweepProgress none(nullptr, 1);
    schedule.forEachGroup(none, "periodic boundary", [](int) { return true; }, [&](int g) {
        const SweepSchedule::Pattern& pattern = schedule.patternOfGroup(g);
        schedule.forDirections(g, [&](size_t d) {
            const SweptLine line = sweptLine(dirs.direction(d), mFlat);
            const Coord& sigma = line.sigma;
            const Vec3d& unit = line.unit;
            const LinePartition part = partition(sigma);
            pattern.sweep->walk(sigma, schedule.reversed(d), lanes.local(),
                [&](uint32_t x, Started& line, bool forward) {
                    if (line.started) return;
                    line.started = true;
                    const int at = entering(part, sigma, pattern.sweep->coord(x),
                        forward ? unit : -unit, forward);
                    if (at >= 0) ++mEnterCount[slice(d) + size_t(at)];
                },
                [](const Started*, size_t, bool) {});
        });
    });
}

FlatAxes
PeriodicBoundary::flatAxes(const Coord& dim, int up)
{
    FlatAxes flat{};
    for (int k = 0; k < 3; ++k) flat[size_t(k)] = k != up && dim[k] == 1;
    return flat;
}

Coord
PeriodicBoundary::copies(const Coord& dim, int up, int minPeriod, size_t directions,
    double depth)
{
    Coord copies(1);
    const int width = minPeriod > 0 ? minPeriod
        : int(std::ceil(0.5 * std::sqrt(double(directions))));
    const FlatAxes flat = flatAxes(dim, up);
    for (int k = 0; k < 3; ++k) {
        if (k == up || flat[size_t(k)] || dim[k] >= width) continue;
        int c = (width + dim[k] - 1) / dim[k];
        if (minPeriod < 0 && depth > 0.0) {
            c = int(std::min<double>(c, std::max(1.0, std::ceil(8.0 / (depth * dim[k])))));
        }
        copies[k] = c;
    }
    return copies;
}

LinePartition
PeriodicBoundary::partition(const Coord& sigma) const
{
    LinePartition part(sigma, LineType::Naive);
    part.centreOn(mMin + mMax);
    return part;
}

int
PeriodicBoundary::layerOf(double height) const
{
    return std::clamp(int(std::floor(height + 0.5)) - mLayer0, 0, mLayers - 1);
}

// Slot of the side face a line at p crosses first going along t (entering: t is minus the
// direction of travel), -1 for the top or bottom.
int
PeriodicBoundary::sideSlot(const Vec3d& p, const Vec3d& t, bool forward) const
{
    double height = 0.0;
    const int face = crossedSide(p, t, mLo, mHi, mUp, height);
    return face < 0 ? -1 : ((forward ? 0 : 1) * 6 + face) * mLayers + layerOf(height);
}

// Slot of the side face and layer that the digital step from voxel a (in the box) to its
// neighbour b on the line (outside) crosses: the step's midpoint height, so that the light
// leaving one face and the lines entering the opposite one are matched without a bias.
// -1: b is above or below the box; -2: b is inside the box (a sparse medium: no face here).
int
PeriodicBoundary::stepSlot(const Coord& a, const Coord& b, bool forward) const
{
    if (b[mUp] < mMin[mUp] || b[mUp] > mMax[mUp]) return -1;
    int face = -1;
    for (int k = 0; k < 3 && face < 0; ++k) {
        if (k == mUp) continue;
        if (b[k] > mMax[k]) face = 2 * k + 1;
        else if (b[k] < mMin[k]) face = 2 * k;
    }
    if (face < 0) return -2;
    return ((forward ? 0 : 1) * 6 + face) * mLayers + layerOf(0.5 * (a[mUp] + b[mUp]));
}

int
PeriodicBoundary::entering(const LinePartition& part, const Coord& sigma, const Coord& first,
    const Vec3d& t, bool forward) const
{
    Coord prev;
    if (stepAlong(part, sigma, first, forward ? -1 : 1, prev)) {
        const int slot = stepSlot(first, prev, forward);
        if (slot != -2) return slot;
    }
    return sideSlot(first.asVec3d(), -t, forward);
}

int
PeriodicBoundary::leaving(const LinePartition& part, const Coord& sigma, const Coord& last,
    const Vec3d& t, bool forward) const
{
    Coord next;
    if (stepAlong(part, sigma, last, forward ? 1 : -1, next)) {
        const int slot = stepSlot(last, next, forward);
        if (slot != -2) return slot;
    }
    return sideSlot(last.asVec3d(), t, forward);
}

// The slot light leaving through slot e re-enters by: the opposite face, same sense, layer.
size_t
PeriodicBoundary::oppositeSlot(size_t e) const
{
    const size_t layer = e % size_t(mLayers), sf = e / size_t(mLayers);
    return ((sf / 6) * 6 + ((sf % 6) ^ 1)) * size_t(mLayers) + layer;
}

double
PeriodicBoundary::rise(const DirectionSet& directions, size_t d) const
{
    const Vec3d unit = directions.unit(d);
    if (unit[mUp] != 0.0) return 0.0;
    const int a1 = (mUp + 1) % 3, a2 = (mUp + 2) % 3;
    const double w1 = mMax[a1] - mMin[a1] + 1;
    const double w2 = mMax[a2] - mMin[a2] + 1;
    // Mean chord of the box's cross-section along the direction: its area over its width seen
    // from the direction. Across a flat axis nothing wraps (the lines are swept in the plane
    // of the others): the chord is then the other axis' width over the slope along it, and a
    // direction along flat axes only never leaves its voxel.
    const bool f1 = mFlat[size_t(a1)], f2 = mFlat[size_t(a2)];
    if ((f1 || unit[a1] == 0.0) && (f2 || unit[a2] == 0.0)) return 0.0;
    const double chord = f1 ? w2 / std::abs(unit[a2])
        : f2 ? w1 / std::abs(unit[a1])
        : w1 * w2 / (w1 * std::abs(unit[a2]) + w2 * std::abs(unit[a1]));
    // The cell spans elevations up to beta = sqrt(Omega) / 2 either way; its half's mean slope
    // is tan(beta / 2).
    const double beta = 0.5 * std::sqrt(kPi * directions.factor(d));
    return chord * std::tan(0.5 * beta);
}

double
PeriodicBoundary::wrap(size_t d, const std::vector<double>& exits, double share, int drift,
    double rise, double upward, std::vector<double>& into, std::array<double, 2>& escaped) const
{
    double transit = 0.0;
    const double shift = drift * rise, whole = std::floor(shift);
    const double part[2] = {1.0 - (shift - whole), shift - whole};
    const size_t size = sliceSize();
    for (size_t e = 0; e < size; ++e) {
        if (exits[e] == 0.0) continue;
        const size_t to = oppositeSlot(e);
        const int layer = int(to % size_t(mLayers));
        for (int k = 0; k < 2; ++k) {
            const double p = share * exits[e] * part[k];
            if (p == 0.0) continue;
            const int at = layer + int(whole) + k;
            const size_t base = to - size_t(layer);
            // No line of the direction may enter the opposite face in that layer (the lines
            // do not repeat with the period): a neighbouring layer that one enters, the lower
            // first for light going down; else, as light that drifted past the top or bottom,
            // it has left.
            int into_at = -1;
            if (at >= 0 && at < mLayers) {
                const double tUp = drift != 0 ? double(drift) : e < size / 2 ? upward : -upward;
                const int first = tUp < 0.0 ? -1 : 1;
                for (int r = 0; r <= kNeighbourLayers && into_at < 0; ++r) {
                    for (int side : {first, -first}) {
                        const int l = at + side * r;
                        if (l >= 0 && l < mLayers && enterCount(d, base + size_t(l)) > 0) {
                            into_at = l;
                            break;
                        }
                        if (r == 0) break;
                    }
                }
            }
            if (into_at >= 0) {
                into[base + size_t(into_at)] += p;
                transit += p;
            } else {
                const double tUp = drift != 0 ? double(drift) : e < size / 2 ? upward : -upward;
                escaped[tUp > 0.0 ? 1 : 0] += p;
            }
        }
    }
    return transit;
}

double
PeriodicBoundary::skyDrift(size_t d, double rise, const std::array<float, 2>& radiance,
    double etendue, std::vector<double>& entry) const
{
    if (rise <= 0.0) return 0.0;
    double added = 0.0;
    // wrap() sends layer l's light to l + whole + k with weight part[k] (per half, share 1/2):
    // where that source layer lies outside the box, the sky sends it instead.
    for (int drift : {1, -1}) {
        const double shift = drift * rise, whole = std::floor(shift);
        const double part[2] = {1.0 - (shift - whole), shift - whole};
        for (size_t sf = 0; sf < 12; ++sf) {
            const double L = radiance[sf / 6];
            if (L == 0.0) continue;
            for (int t = 0; t < mLayers; ++t) {
                const size_t e = sf * size_t(mLayers) + size_t(t);
                const uint32_t lines = enterCount(d, e);
                if (lines == 0) continue;
                double outside = 0.0;
                for (int k = 0; k < 2; ++k) {
                    const int from = t - int(whole) - k;
                    if (from < 0 || from >= mLayers) outside += part[k];
                }
                const double p = 0.5 * outside * L * etendue * lines;
                entry[e] += p;
                added += p;
            }
        }
    }
    return added;
}

} // namespace vdbrad
