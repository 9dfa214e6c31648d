#include "vdbrad/sweep/RayCastVisibility.h"

#include <algorithm>
#include <array>
#include <cstdlib>

namespace vdbrad {

RayCastVisibility::RayCastVisibility(const VoxelIndex& index,
    const std::vector<openvdb::Vec3f>& normals, LineType lines, float depth,
    const std::vector<uint32_t>* regions)
    : mIndex(index), mNormals(normals), mRegions(regions), mLines(lines), mDepth(depth)
    , mBox(index.bbox())
{
}

RayCastVisibility::Line
RayCastVisibility::makeLine(const openvdb::Coord& sigma) const
{
    LinePartition partition(sigma, mLines);
    // The sweeps' lines: centred on the same box (LineSweep::assignLines).
    partition.centreOn(mBox.min() + mBox.max());
    const int axis = partition.majorAxis();
    const int64_t sign = partition.signs()[size_t(axis)];
    const int64_t lo = sign * mBox.min()[axis], hi = sign * mBox.max()[axis];
    return Line{partition, sigma,
        openvdb::Vec3f(float(sigma.x()), float(sigma.y()), float(sigma.z())),
        std::min(lo, hi), std::max(lo, hi)};
}

uint32_t
RayCastVisibility::seen(const Line& line, Accessor& acc, uint32_t x,
    float travel) const
{
    using openvdb::Coord;
    const LinePartition& p = line.partition;
    const openvdb::Vec3f t = line.s * travel;
    const Coord cx = mIndex.coord(x);
    const LineKey key = p.key(cx);
    const Coord kx = p.canonical(cx);
    const int64_t posX = p.position(cx);
    const Coord abc = p.canonicalDirection();
    const int64_t a = abc[0];
    // Walk against the light: towards smaller canonical major coordinates if it travels +sigma.
    const int walk = travel > 0.f ? -1 : 1;
    const uint32_t rx = region(x);
    uint32_t cur = x;

    struct Met { int64_t pos; uint32_t index; Coord c; };
    for (int64_t X = kx[0]; X >= line.majorLo && X <= line.majorHi;) {
        // The slice's minor coordinates: those whose line indices are the line's. A slice's
        // values lie in [L, L + w/a) with w/a < 2 and L moving by b/a per slice, so they are
        // within (-2, 3) of the guess below: its offsets -1..2.
        const int64_t dX = X - kx[0];
        std::array<int32_t, 4> ys{}, zs{};
        size_t ny = 0, nz = 0;
        const int64_t gy = kx[1] + floorDiv(abc[1] * dX, a);
        const int64_t gz = kx[2] + floorDiv(abc[2] * dX, a);
        for (int64_t d = -1; d <= 2; ++d) {
            const Coord cy = p.fromCanonical(Coord(int32_t(X), int32_t(gy + d), kx[2]));
            if (p.key(cy).i == key.i) ys[ny++] = int32_t(gy + d);
            const Coord cz = p.fromCanonical(Coord(int32_t(X), kx[1], int32_t(gz + d)));
            if (p.key(cz).j == key.j) zs[nz++] = int32_t(gz + d);
        }

        std::array<Met, 16> met;
        size_t count = 0;
        for (size_t u = 0; u < ny; ++u) {
            for (size_t v = 0; v < nz; ++v) {
                const Coord c = p.fromCanonical(Coord(int32_t(X), ys[u], zs[v]));
                const int64_t pos = p.position(c);
                if (X == kx[0] && (walk < 0 ? pos >= posX : pos <= posX)) continue;
                const int32_t index = acc.getValue(c);
                if (index >= 0) met[count++] = Met{pos, uint32_t(index), c};
            }
        }
        std::sort(met.begin(), met.begin() + long(count), [&](const Met& m, const Met& n) {
            return walk < 0 ? m.pos > n.pos : m.pos < n.pos;
        });
        // The exchange rule (LineSweep.h) on the chain from x back to the first sender.
        for (size_t k = 0; k < count; ++k) {
            const uint32_t v = met[k].index;
            if (t.dot(mNormals[v]) > 0.f) return region(v) == rx ? v : kNone;
            if ((mIndex.coord(cur) - met[k].c).asVec3s().dot(mNormals[v]) <= -mDepth) {
                return kNone;
            }
            if (region(v) != rx) return kNone;
            cur = v;
        }

        // Nothing here: if the slice lies in an empty node, jump over the slices that
        // certainly stay inside it. A slice deviates from the straight line by < 2 voxels
        // on each minor axis, hence the margins of 2.
        int64_t step = 1;
        if (count == 0 && ny > 0 && nz > 0) {
            const Coord c0 = p.fromCanonical(Coord(int32_t(X), ys[0], zs[0]));
            const int64_t size = VoxelIndex::emptyNodeSide(acc, c0);
            if (size > 1 && !acc.isValueOn(c0)) {
                int64_t m = std::numeric_limits<int64_t>::max();
                for (int k = 0; k < 3; ++k) {
                    const int64_t lo = int64_t(c0[k]) & ~(size - 1), hi = lo + size - 1;
                    const int64_t motion = int64_t(walk) * line.sigma[k];   // original axis k
                    const int64_t ahead = motion >= 0 ? hi - c0[k] : c0[k] - lo;
                    const int64_t behind = motion >= 0 ? c0[k] - lo : hi - c0[k];
                    if (behind < 2 || (motion == 0 && ahead < 2)) m = 0;
                    else if (motion != 0) m = std::min(m, (ahead - 2) * a / std::abs(motion));
                }
                step = std::max<int64_t>(m, 1);
            }
        }
        X += walk * step;
    }
    return kNone;
}

} // namespace vdbrad
