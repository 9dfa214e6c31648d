// LineSweep: who sees whom along the digital lines of one direction (thesis §4.3.3).
//
// For a direction sigma, every surface voxel lies on one digital line (LinePartition). Visiting
// the voxels in a LeafOrder whose signs match sigma meets the voxels of every line in their order
// along the line, so a single streaming pass that keeps, per line, only the last voxel met (the
// "frontier") finds every pair of consecutive voxels: no line lists, no sorting. The pass in
// reverse order serves -sigma.
//
// Visibility rule, for light travelling along t (t = sigma on the forward pass, -sigma on the
// backward one), with d(v) = t . n_v:
//   - a sender (d > 0: its front faces along t) replaces what travels on the line: the next
//     voxels see it;
//   - a receiver (d < 0: its front faces the incoming light) sees what travels on the line and
//     lets it pass, so that the neighbours of a flat wall, which digital lines at grazing angles
//     run through one after the other, do not hide each other; the same holds for d = 0;
//   - but a receiver x that lies behind the surface of the receiver p met just before it,
//     (c_x - c_p) . n_p <= -depth, is hidden by p's solid: it sees nothing (p's back is black).
//     That is what stops light at one-voxel walls: behind a wall voxel that lets light pass,
//     the next voxel is a sender (the wall's other side replaces the light) or lies behind the
//     wall's plane. `depth` (voxels, default 1) keeps the digitisation noise of one surface
//     (voxel centres scatter up to ~0.87 voxel around a curved or tilted plane) from hiding its
//     own neighbours.
//   - light passes only between voxels that face the same air region (Enclosure.h), so a ray
//     leaving a room through the corner voxel it starts from reaches nothing outside.
// Each receiver is reported once per direction with the voxel it sees, or none (the open sky, or
// a back).
#pragma once

#include "vdbrad/LeafOrder.h"
#include "vdbrad/LinePartition.h"
#include "vdbrad/VoxelIndex.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <limits>
#include <unordered_map>
#include <vector>

namespace vdbrad {

class LineSweep
{
public:
    static constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

    /// @param voxels   the surface voxels
    /// @param normals  index-space unit normals, one per voxel
    /// @param depth    occlusion depth in voxels (see the file comment), > 0
    /// @param regions  per voxel, the air region it faces (Enclosure.h); may be null (one region)
    LineSweep(const VoxelIndex& voxels, const std::vector<openvdb::Vec3f>& normals,
        LineType lines, float depth = 1.f, const std::vector<uint32_t>* regions = nullptr)
        : mVoxels(voxels), mNormals(normals), mRegions(regions), mLines(lines), mDepth(depth)
    {
        const openvdb::CoordBBox box = voxels.bbox();
        mMin = box.min();
        mMax = box.max();
    }

    /// @brief Report, for every voxel x that faces sigma or -sigma, the voxel it sees:
    /// visit(x, y, sigmaDotN) with sigmaDotN = sigma . n_x (> 0: x looks along +sigma, < 0:
    /// along -sigma) and y the seen voxel or kNone. Sequential: run one direction per thread.
    /// @param order     the LeafOrder of LeafOrder::baseSigns(sigma, reversed)
    /// @param reversed  as returned by LeafOrder::baseSigns for sigma
    template<typename VisitT>
    void sweep(const openvdb::Coord& sigma, const LeafOrder& order, bool reversed,
        VisitT&& visit) const
    {
        LinePartition partition(sigma, mLines);
        // Centred on the scene so that a symmetric scene gets symmetric lines.
        partition.centreOn(mMin + mMax);
        // Dense frontier over the lines crossing the bounding box when that is not much larger
        // than the scene; hashed otherwise (a few small objects far apart).
        int64_t i0 = std::numeric_limits<int64_t>::max(), i1 = std::numeric_limits<int64_t>::min();
        int64_t j0 = i0, j1 = i1;
        for (int c = 0; c < 8; ++c) {
            const openvdb::Coord corner(c & 1 ? mMax.x() : mMin.x(), c & 2 ? mMax.y() : mMin.y(),
                c & 4 ? mMax.z() : mMin.z());
            const LineKey k = partition.key(corner);
            i0 = std::min(i0, k.i); i1 = std::max(i1, k.i);
            j0 = std::min(j0, k.j); j1 = std::max(j1, k.j);
        }
        const double lines = double(i1 - i0 + 1) * double(j1 - j0 + 1);
        if (lines <= 4.0 * double(mVoxels.size()) + 65536.0) {
            const int64_t nj = j1 - j0 + 1;
            std::vector<Front> table(static_cast<size_t>(lines));
            auto slot = [&](const LineKey& k) -> Front& {
                return table[size_t((k.i - i0) * nj + (k.j - j0))];
            };
            pass(partition, order, reversed, +1.f, slot, visit);
            std::fill(table.begin(), table.end(), Front());
            pass(partition, order, reversed, -1.f, slot, visit);
        } else {
            std::unordered_map<LineKey, Front, LineKeyHash> table;
            table.reserve(mVoxels.size());
            auto slot = [&](const LineKey& k) -> Front& { return table[k]; };
            pass(partition, order, reversed, +1.f, slot, visit);
            table.clear();
            pass(partition, order, reversed, -1.f, slot, visit);
        }
    }

private:
    // Per line: the last voxel met, and what a receiver right after it sees (if not behind it).
    struct Front { uint32_t last = kNone; uint32_t seen = kNone; };

    /// One streaming pass with light travelling along travel * sigma.
    template<typename SlotT, typename VisitT>
    void pass(const LinePartition& partition, const LeafOrder& order, bool reversed, float travel,
        SlotT& slot, VisitT& visit) const
    {
        const openvdb::Coord& sigma = partition.direction();
        const openvdb::Vec3f t = openvdb::Vec3f(float(sigma.x()), float(sigma.y()),
            float(sigma.z())) * travel;
        // The LeafOrder runs along +sigma, or along -sigma when `reversed`.
        const bool backwards = (travel > 0.f) == reversed;
        const std::vector<uint32_t>& seq = order.voxels();
        const size_t n = seq.size();
        for (size_t k = 0; k < n; ++k) {
            const uint32_t x = seq[backwards ? n - 1 - k : k];
            const openvdb::Coord& cx = mVoxels.coord(x);
            Front& f = slot(partition.key(cx));
            const float dx = t.dot(mNormals[x]);
            uint32_t seen = f.seen;
            if (seen != kNone && f.last != seen) {
                // The previous voxel let the light pass: x is hidden if it lies behind it.
                const openvdb::Vec3f& np = mNormals[f.last];
                if ((cx - mVoxels.coord(f.last)).asVec3s().dot(np) <= -mDepth) seen = kNone;
            }
            if (seen != kNone && mRegions && (*mRegions)[x] != (*mRegions)[seen]) seen = kNone;
            if (dx < 0.f) visit(x, seen, dx * travel);   // = sigma . n_x
            f.last = x;
            f.seen = dx > 0.f ? x : seen;
        }
    }

    const VoxelIndex& mVoxels;
    const std::vector<openvdb::Vec3f>& mNormals;
    const std::vector<uint32_t>* mRegions;
    LineType mLines;
    float mDepth;
    openvdb::Coord mMin, mMax;
};

} // namespace vdbrad
