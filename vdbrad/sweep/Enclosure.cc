#include "vdbrad/sweep/Enclosure.h"

#include <openvdb/util/NodeMasks.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <array>
#include <cmath>
#include <cstdlib>
#include <unordered_map>

namespace vdbrad {

namespace {

// The 512 cells of one 8^3 block in OpenVDB's leaf layout: word x, bit (y << 3) | z.
struct Mask
{
    std::array<uint64_t, 8> w{};

    static int offset(const openvdb::Coord& c)
    {
        return ((c.x() & 7) << 6) | ((c.y() & 7) << 3) | (c.z() & 7);
    }
    bool test(int i) const { return ((w[i >> 6] >> (i & 63)) & 1u) != 0; }
    void set(int i) { w[i >> 6] |= uint64_t(1) << (i & 63); }
    bool any() const
    {
        uint64_t a = 0;
        for (const uint64_t v : w) a |= v;
        return a != 0;
    }
    bool operator==(const Mask& m) const { return w == m.w; }
    Mask operator&(const Mask& m) const
    {
        Mask r;
        for (int x = 0; x < 8; ++x) r.w[x] = w[x] & m.w[x];
        return r;
    }
    Mask operator~() const
    {
        Mask r;
        for (int x = 0; x < 8; ++x) r.w[x] = ~w[x];
        return r;
    }
};

constexpr uint64_t kBytes = 0x0101010101010101ull;   // bit z = 0 of every row (x, y)

// Cell (x, y, z) moved to (x, y, z) + @a d, |d| <= 7 per axis; cells leaving the block drop out.
Mask
shifted(const Mask& m, const openvdb::Coord& d)
{
    const uint64_t zKeep = kBytes * (d.z() >= 0 ? (0xFFu << d.z()) & 0xFFu : 0xFFu >> -d.z());
    Mask r;
    for (int x = 0; x < 8; ++x) {
        const int from = x - d.x();
        if (from < 0 || from > 7) continue;
        uint64_t v = m.w[from];
        v = (d.z() >= 0 ? v << d.z() : v >> -d.z()) & zKeep;
        r.w[x] = d.y() >= 0 ? v << (8 * d.y()) : v >> (-8 * d.y());
    }
    return r;
}

// @a m grown by one cell along the connectivity of @a lines (3^3 box or face neighbours).
Mask
dilated(const Mask& m, LineType lines)
{
    auto alongZ = [](uint64_t v) {
        return v | ((v << 1) & (kBytes * 0xFEu)) | ((v >> 1) & (kBytes * 0x7Fu));
    };
    Mask r;
    if (lines == LineType::Naive) {
        std::array<uint64_t, 8> yz;
        for (int x = 0; x < 8; ++x) {
            const uint64_t v = alongZ(m.w[x]);
            yz[x] = v | (v << 8) | (v >> 8);
        }
        for (int x = 0; x < 8; ++x) {
            r.w[x] = yz[x] | (x > 0 ? yz[x - 1] : 0) | (x < 7 ? yz[x + 1] : 0);
        }
    } else {
        for (int x = 0; x < 8; ++x) {
            const uint64_t v = m.w[x];
            r.w[x] = alongZ(v) | (v << 8) | (v >> 8) | (x > 0 ? m.w[x - 1] : 0)
                | (x < 7 ? m.w[x + 1] : 0);
        }
    }
    return r;
}

// The cells of a block on its face, edge or corner towards neighbour offset @a d.
Mask
boundary(const openvdb::Coord& d)
{
    uint64_t row = ~uint64_t(0);
    if (d.y() != 0) row &= d.y() > 0 ? uint64_t(0xFF) << 56 : uint64_t(0xFF);
    if (d.z() != 0) row &= d.z() > 0 ? kBytes << 7 : kBytes;
    Mask r;
    for (int x = 0; x < 8; ++x) {
        if (d.x() == 0 || x == (d.x() > 0 ? 7 : 0)) r.w[x] = row;
    }
    return r;
}

// The connected components of the empty cells of a block with walls @a walls, in the order of
// their lowest cell: a flood fill by whole-mask dilations, a few dozen word operations per step.
std::vector<Mask>
components(const Mask& walls, LineType lines)
{
    std::vector<Mask> out;
    Mask empty = ~walls;
    for (int x = 0; x < 8; ++x) {
        while (empty.w[x] != 0) {
            Mask part;
            part.w[x] = empty.w[x] & (~empty.w[x] + 1);   // lowest empty cell
            for (;;) {
                const Mask grown = dilated(part, lines) & empty;
                if (grown == part) break;
                part = grown;
            }
            out.push_back(part);
            empty = empty & ~part;
        }
    }
    return out;
}

// Marks a block entry of the union-find array as a block holding walls; the rest is its leaf.
// Node ids stay below it.
constexpr uint32_t kWall = uint32_t(1) << 31;
constexpr uint32_t kNone = ~uint32_t(0);
// Leaves with more components than this get a cell -> component table (a 3D checkerboard of walls
// has up to 256): lookups stay constant-time instead of a scan over the components.
constexpr size_t kScanComponents = 8;

openvdb::CoordBBox
blockBox(const VoxelIndex& voxels)
{
    const openvdb::CoordBBox box = voxels.bbox();
    return openvdb::CoordBBox((box.min() >> 3) - openvdb::Coord(1),
        (box.max() >> 3) + openvdb::Coord(1));
}

// Each leaf's own components, in parallel (they depend on its walls only).
std::vector<std::vector<Mask>>
leafComponents(const VoxelIndex& voxels, LineType lines)
{
    const size_t leaves = voxels.leafCount();
    std::vector<std::vector<Mask>> parts(leaves);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leaves),
        [&](const tbb::blocked_range<size_t>& r) {
            for (size_t n = r.begin(); n != r.end(); ++n) {
                if (voxels.leafBegin(n) == voxels.leafBegin(n + 1)) continue;   // an empty block
                Mask walls;
                for (size_t i = voxels.leafBegin(n); i != voxels.leafBegin(n + 1); ++i) {
                    walls.set(Mask::offset(voxels.coord(i)));
                }
                parts[n] = components(walls, lines);
            }
        });
    return parts;
}

// "Forward" neighbour offsets (first nonzero coordinate positive) visit each neighbouring pair
// once.
bool
isForward(const openvdb::Coord& d)
{
    return d.x() > 0 || (d.x() == 0 && (d.y() > 0 || (d.y() == 0 && d.z() > 0)));
}

// Neighbour offsets with the connectivity of the lines, and the forward ones among them.
void
neighbourOffsets(LineType lines, std::vector<openvdb::Coord>& offsets,
    std::vector<openvdb::Coord>& forward)
{
    for (int i = -1; i <= 1; ++i) for (int j = -1; j <= 1; ++j) for (int k = -1; k <= 1; ++k) {
        const int m = std::abs(i) + std::abs(j) + std::abs(k);
        if (m == 0 || (lines == LineType::Standard && m > 1)) continue;
        offsets.emplace_back(i, j, k);
        if (isForward(offsets.back())) forward.push_back(offsets.back());
    }
}

// The nodes of the empty cells and their union-find: every block of @a blocks (those holding
// walls stay unused), then every component of every leaf. Each root is the smallest id of its
// set: parents never exceed their child, so one pass in id order flattens it, and the sets (all
// the result depends on) are the same whatever order the unions come in.
struct RegionGraph
{
    const VoxelIndex& voxels;
    const LineType lines;
    const openvdb::CoordBBox blocks;
    const openvdb::Coord dim;
    const uint64_t ny, nz;
    std::vector<std::vector<Mask>> parts;             // each leaf's components
    std::vector<uint32_t> firstPart;                  // each leaf's first component node
    uint64_t nodes = 0;
    std::vector<std::array<uint16_t, 512>> tables;    // cell -> component, 0xFFFF at walls
    std::vector<uint32_t> tableOf;                    // each leaf's table, or kNone
    std::vector<uint32_t> parent;                     // the union-find array

    RegionGraph(const VoxelIndex& v, LineType l, const openvdb::CoordBBox& b)
        : voxels(v), lines(l), blocks(b), dim(b.dim()), ny(uint64_t(dim.y()))
        , nz(uint64_t(dim.z()))
    {
    }

    uint64_t blockOf(const openvdb::Coord& b) const;   // b in block coordinates
    int partAt(size_t n, int offset) const;
    uint32_t find(uint32_t x);
    void unite(uint32_t a, uint32_t b);
    bool numberNodes(uint64_t blockCount);
    void buildTables();
    void initialiseSets();
    void joinEmptyBlocks(const std::vector<openvdb::Coord>& forward);
    void joinLeaves(const std::vector<openvdb::Coord>& offsets);
    void joinAcross(size_t n, size_t j, size_t m, const openvdb::Coord& d, const Mask& across);
    void flatten();
    void findFronts(const std::vector<openvdb::Vec3f>& normals, std::vector<uint32_t>& region)
        const;
};

inline uint64_t
RegionGraph::blockOf(const openvdb::Coord& b) const
{
    return (uint64_t(b.x() - blocks.min().x()) * ny + uint64_t(b.y() - blocks.min().y())) * nz
        + uint64_t(b.z() - blocks.min().z());
}

// Local component of leaf @a n holding cell @a offset, or -1 at a wall.
inline int
RegionGraph::partAt(size_t n, int offset) const
{
    if (tableOf[n] != kNone) {
        const uint16_t j = tables[tableOf[n]][offset];
        return j == 0xFFFF ? -1 : int(j);
    }
    for (size_t j = 0; j < parts[n].size(); ++j) {
        if (parts[n][j].test(offset)) return int(j);
    }
    return -1;
}

inline uint32_t
RegionGraph::find(uint32_t x)
{
    while (parent[x] != x) {
        parent[x] = parent[parent[x]];   // path halving
        x = parent[x];
    }
    return x;
}

inline void
RegionGraph::unite(uint32_t a, uint32_t b)
{
    a = find(a);
    b = find(b);
    if (a < b) parent[b] = a;
    else if (b < a) parent[a] = b;
}

// Each leaf's first node after the @a blockCount block nodes; false if the ids would reach kWall.
bool
RegionGraph::numberNodes(uint64_t blockCount)
{
    const size_t leaves = voxels.leafCount();
    firstPart.resize(leaves);
    nodes = blockCount;
    for (size_t n = 0; n < leaves; ++n) {
        firstPart[n] = uint32_t(nodes);
        nodes += parts[n].size();
        if (nodes >= kWall) return false;
    }
    return true;
}

// Cell -> component tables for leaves with many components, 0xFFFF at walls.
void
RegionGraph::buildTables()
{
    const size_t leaves = voxels.leafCount();
    tableOf.assign(leaves, kNone);
    for (size_t n = 0; n < leaves; ++n) {
        if (parts[n].size() <= kScanComponents) continue;
        tableOf[n] = uint32_t(tables.size());
        tables.emplace_back();
        tables.back().fill(0xFFFF);
        for (size_t j = 0; j < parts[n].size(); ++j) {
            for (int i = 0; i < 512; ++i) {
                if (parts[n][j].test(i)) tables.back()[i] = uint16_t(j);
            }
        }
    }
}

// Every node its own set; the entry of a block holding walls names its leaf instead.
void
RegionGraph::initialiseSets()
{
    parent.resize(nodes);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, nodes),
        [&](const tbb::blocked_range<size_t>& r) {
            for (size_t i = r.begin(); i != r.end(); ++i) parent[i] = uint32_t(i);
        });
    for (size_t n = 0; n < voxels.leafCount(); ++n) {
        if (voxels.leafBegin(n) == voxels.leafBegin(n + 1)) continue;
        parent[blockOf(voxels.leafOrigin(n) >> 3)] = kWall | uint32_t(n);
    }
}

// Empty blocks joined to their empty neighbours.
void
RegionGraph::joinEmptyBlocks(const std::vector<openvdb::Coord>& forward)
{
    std::vector<int64_t> steps;
    for (const openvdb::Coord& d : forward) {
        steps.push_back((int64_t(d.x()) * int64_t(ny) + d.y()) * int64_t(nz) + d.z());
    }
    uint64_t b = 0;
    for (int x = 0; x < dim.x(); ++x) for (int y = 0; y < dim.y(); ++y) {
        for (int z = 0; z < dim.z(); ++z, ++b) {
            if (parent[b] & kWall) continue;
            for (size_t s = 0; s < forward.size(); ++s) {
                const openvdb::Coord& d = forward[s];
                if (x + d.x() >= dim.x() || y + d.y() < 0 || y + d.y() >= dim.y()
                    || z + d.z() < 0 || z + d.z() >= dim.z()) continue;
                const uint64_t nb = uint64_t(int64_t(b) + steps[s]);
                if (!(parent[nb] & kWall)) unite(uint32_t(b), uint32_t(nb));
            }
        }
    }
}

// Blocks with walls joined to their neighbours: every component touching an empty neighbour
// block joins it; components of two neighbouring leaves join where a cell of one is a
// neighbour of a cell of the other (joinAcross()).
void
RegionGraph::joinLeaves(const std::vector<openvdb::Coord>& offsets)
{
    std::vector<Mask> toward(offsets.size());
    for (size_t s = 0; s < offsets.size(); ++s) toward[s] = boundary(offsets[s]);
    // offsets are symmetric in their listing: -offsets[s] is offsets[size - 1 - s]
    for (size_t n = 0; n < voxels.leafCount(); ++n) {
        if (parts[n].empty()) continue;
        const openvdb::Coord block = voxels.leafOrigin(n) >> 3;
        for (size_t s = 0; s < offsets.size(); ++s) {
            const openvdb::Coord& d = offsets[s];
            const uint64_t nb = blockOf(block + d);
            const uint32_t e = parent[nb];
            if (!(e & kWall)) {
                for (size_t j = 0; j < parts[n].size(); ++j) {
                    if ((parts[n][j] & toward[s]).any()) {
                        unite(uint32_t(firstPart[n] + j), uint32_t(nb));
                    }
                }
                continue;
            }
            if (!isForward(-d)) continue;   // a pair of leaves is visited from the forward one
            const size_t m = e & ~kWall;
            const Mask& across = toward[offsets.size() - 1 - s];
            for (size_t j = 0; j < parts[n].size(); ++j) {
                if (!(parts[n][j] & toward[s]).any()) continue;
                joinAcross(n, j, m, d, across);
            }
        }
    }
}

// Component @a j of leaf @a n joined to the components of leaf @a m (block offset @a d away)
// that hold a neighbour of one of its cells: its boundary cells moved across, grown by one cell
// along the boundary (@a across: m's boundary cells towards n) for naive lines.
void
RegionGraph::joinAcross(size_t n, size_t j, size_t m, const openvdb::Coord& d,
    const Mask& across)
{
    Mask touched = shifted(parts[n][j], openvdb::Coord(-7 * d.x(), -7 * d.y(), -7 * d.z()));
    if (lines == LineType::Naive) touched = dilated(touched, lines) & across;
    for (int x = 0; x < 8; ++x) {
        while (touched.w[x] != 0) {
            const int i = 64 * x + int(openvdb::util::FindLowestOn(touched.w[x]));
            touched.w[x] &= touched.w[x] - 1;
            const int k = partAt(m, i);
            if (k < 0) continue;
            unite(uint32_t(firstPart[n] + j), uint32_t(firstPart[m] + size_t(k)));
            touched = touched & ~parts[m][size_t(k)];
        }
    }
}

// Every node's parent made its set's root: one pass in id order, as roots are smallest.
void
RegionGraph::flatten()
{
    for (uint32_t& p : parent) {
        if (!(p & kWall)) p = parent[p];
    }
}

// Each voxel's front cell (the first empty cell stepping along its normal), as the root of its
// set, or kNone.
void
RegionGraph::findFronts(const std::vector<openvdb::Vec3f>& normals,
    std::vector<uint32_t>& region) const
{
    const openvdb::CoordBBox inside = voxels.bbox().expandBy(1);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, voxels.size()),
        [&](const tbb::blocked_range<size_t>& r) {
            for (size_t v = r.begin(); v != r.end(); ++v) {
                const openvdb::Coord& c = voxels.coord(v);
                const openvdb::Vec3f& nrm = normals[v];
                uint32_t front = kNone;
                for (int k = 1; k <= 3 && front == kNone; ++k) {
                    const openvdb::Coord q = c + openvdb::Coord(int(std::lround(k * nrm[0])),
                        int(std::lround(k * nrm[1])), int(std::lround(k * nrm[2])));
                    if (!inside.isInside(q)) break;
                    const uint64_t b = blockOf(q >> 3);
                    const uint32_t e = parent[b];
                    if (!(e & kWall)) {
                        front = e;
                    } else {
                        const int j = partAt(e & ~kWall, Mask::offset(q));
                        if (j >= 0) front = parent[firstPart[e & ~kWall] + uint32_t(j)];
                    }
                }
                region[v] = front;
            }
        });
}

// Cavities numbered in voxel order; the outside is the set @a outside (the domain's corner
// block's): the front roots in @a out.region become region numbers.
void
numberCavities(uint32_t outside, Regions& out)
{
    std::unordered_map<uint32_t, uint32_t> cavity;
    for (uint32_t& r : out.region) {
        if (r == kNone || r == outside) {
            r = 0;
            continue;
        }
        auto it = cavity.emplace(r, out.cavities + 1).first;
        if (it->second > out.cavities) out.cavities = it->second;
        r = it->second;
    }
}

} // namespace

uint64_t
regionBlocks(const VoxelIndex& voxels)
{
    if (voxels.empty()) return 0;
    const openvdb::Coord dim = blockBox(voxels).dim();
    return uint64_t(dim.x()) * uint64_t(dim.y()) * uint64_t(dim.z());
}

size_t
regionsBytes(const VoxelIndex& voxels)
{
    // Per block its union-find entry; per leaf its component list (vector, allocation, start) and
    // two components (mask and union-find entry); per voxel nothing: fronts live in the result.
    return size_t(4 * regionBlocks(voxels)) + voxels.leafCount() * (24 + 16 + 4 + 2 * (64 + 4));
}

Regions
findRegions(const VoxelIndex& voxels, const std::vector<openvdb::Vec3f>& normals,
    LineType lines, uint64_t maxBlocks)
{
    Regions out;
    out.region.assign(voxels.size(), 0);
    if (voxels.empty()) return out;
    // The blocks of the bounding box grown by one block: the outer layer holds no wall, so it is
    // one connected piece of the outside, and the fill needs no bounds checks at leaves.
    const openvdb::CoordBBox blocks = blockBox(voxels);
    const openvdb::Coord dim = blocks.dim();
    const uint64_t blockCount = uint64_t(dim.x()) * uint64_t(dim.y()) * uint64_t(dim.z());
    if (blockCount > maxBlocks) return out;
    RegionGraph graph(voxels, lines, blocks);
    graph.parts = leafComponents(voxels, lines);
    if (!graph.numberNodes(blockCount)) return out;
    out.analysed = true;
    graph.buildTables();

    graph.initialiseSets();
    std::vector<openvdb::Coord> offsets, forward;
    neighbourOffsets(lines, offsets, forward);
    graph.joinEmptyBlocks(forward);
    graph.joinLeaves(offsets);
    graph.flatten();

    // Each voxel's front cell, as the root of its set, kept in the result until it is numbered.
    graph.findFronts(normals, out.region);
    numberCavities(graph.parent[0], out);
    // A voxel buried in walls (no empty cell within 3 steps along its normal) stays region 0.
    return out;
}

} // namespace vdbrad
