// The reference for Enclosure's findRegions(): its former dense implementation, a breadth-first
// fill over every cell of the bounding box. Shared by tests/test_enclosure.cc (identical regions
// on random scenes) and benchmarks/bench_extremes.cc (old against new time); not in the library.
#pragma once

#include "vdbrad/sweep/Enclosure.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdint>
#include <functional>
#include <unordered_map>
#include <vector>

namespace vdbrad {
namespace test {

/// The dense fill findRegions() used before it worked on blocks (commit e254c97), unchanged but
/// for its name: one bit per cell of the bounding box grown by two, breadth-first.
inline Regions
denseRegions(const VoxelIndex& voxels, const std::vector<openvdb::Vec3f>& normals,
    LineType lines, uint64_t maxCells = uint64_t(1) << 31)
{
    Regions out;
    out.region.assign(voxels.size(), 0);
    if (voxels.empty()) return out;
    // The box grown by two cells: the outer layer is marked as visited up front, so the fill
    // never steps outside and needs no bounds checks; the layer inside it is empty (the outside).
    const openvdb::CoordBBox box = voxels.bbox().expandBy(2);
    const openvdb::Coord dim = box.dim();
    const uint64_t ny = uint64_t(dim.y()), nz = uint64_t(dim.z());
    const uint64_t cells = uint64_t(dim.x()) * ny * nz;
    if (cells > maxCells) return out;
    out.analysed = true;

    auto linear = [&](const openvdb::Coord& c) {
        return (uint64_t(c.x() - box.min().x()) * ny + uint64_t(c.y() - box.min().y())) * nz
            + uint64_t(c.z() - box.min().z());
    };
    // One bit per cell: set = a surface voxel, or an air cell some fill has reached.
    std::vector<uint64_t> bits((cells + 63) / 64, 0);
    auto test = [&](uint64_t i) { return ((bits[i >> 6] >> (i & 63)) & 1u) != 0; };
    auto set = [&](uint64_t i) { bits[i >> 6] |= uint64_t(1) << (i & 63); };
    for (const openvdb::Coord& c : voxels.coords()) set(linear(c));
    const std::vector<uint64_t> walls = bits;
    auto isWall = [&](uint64_t i) { return ((walls[i >> 6] >> (i & 63)) & 1u) != 0; };

    // Each voxel's front cell: the first empty cell stepping along its normal.
    std::vector<uint64_t> front(voxels.size(), ~uint64_t(0));
    const openvdb::CoordBBox inside = voxels.bbox().expandBy(1);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, voxels.size()),
        [&](const tbb::blocked_range<size_t>& r) {
            for (size_t v = r.begin(); v != r.end(); ++v) {
                const openvdb::Coord& c = voxels.coord(v);
                const openvdb::Vec3f& n = normals[v];
                for (int k = 1; k <= 3; ++k) {
                    const openvdb::Coord q = c + openvdb::Coord(int(std::lround(k * n[0])),
                        int(std::lround(k * n[1])), int(std::lround(k * n[2])));
                    if (!inside.isInside(q)) break;
                    const uint64_t i = linear(q);
                    if (!isWall(i)) { front[v] = i; break; }
                }
            }
        });

    std::vector<int64_t> offsets;
    for (int i = -1; i <= 1; ++i) for (int j = -1; j <= 1; ++j) for (int k = -1; k <= 1; ++k) {
        const int m = std::abs(i) + std::abs(j) + std::abs(k);
        if (m == 0 || (lines == LineType::Standard && m > 1)) continue;
        offsets.push_back((int64_t(i) * int64_t(ny) + j) * int64_t(nz) + k);
    }
    // The outer layer counts as visited: the fill stops there.
    for (int axis = 0; axis < 3; ++axis) {
        for (int side = 0; side < 2; ++side) {
            openvdb::CoordBBox face = box;
            face.min()[axis] = face.max()[axis] = side ? box.max()[axis] : box.min()[axis];
            for (auto it = face.beginXYZ(); it; ++it) set(linear(*it));
        }
    }
    // Breadth-first fill; the frontier of a fill through mostly empty space is a surface, not a
    // volume, so it stays small.
    std::vector<uint64_t> current, next;
    auto fill = [&](const std::function<void(uint64_t)>& onCell) {
        while (!current.empty()) {
            next.clear();
            for (const uint64_t c : current) {
                for (const int64_t o : offsets) {
                    const uint64_t i = uint64_t(int64_t(c) + o);
                    if (test(i)) continue;
                    set(i);
                    onCell(i);
                    next.push_back(i);
                }
            }
            current.swap(next);
        }
    };
    // The outside: from one cell of the empty layer inside the border (it is connected).
    {
        const uint64_t start = linear(box.min() + openvdb::Coord(1));
        set(start);
        current.assign(1, start);
        fill([](uint64_t) {});
    }

    // Cavities: fill again from every front cell the outside fill did not reach, numbering as
    // we go; only front cells need their number remembered.
    std::unordered_map<uint64_t, uint32_t> cavityOf;
    for (size_t v = 0; v < voxels.size(); ++v) {
        if (front[v] != ~uint64_t(0) && !test(front[v])) cavityOf.emplace(front[v], 0u);
    }
    for (size_t v = 0; v < voxels.size(); ++v) {
        const uint64_t f = front[v];
        if (f == ~uint64_t(0)) continue;
        auto it = cavityOf.find(f);
        if (it == cavityOf.end()) continue;      // outside: region 0
        if (it->second == 0) {
            const uint32_t id = ++out.cavities;
            it->second = id;
            set(f);
            current.assign(1, f);
            fill([&](uint64_t i) {
                auto c = cavityOf.find(i);
                if (c != cavityOf.end()) c->second = id;
            });
        }
        out.region[v] = it->second;
    }
    // A voxel buried in walls (no empty cell within 3 steps along its normal) stays region 0.
    return out;
}

} // namespace test
} // namespace vdbrad
