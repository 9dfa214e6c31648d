#include "vdbrad/core/VoxelIndex.h"
#include "vdbrad/core/ProcessInfo.h"

#include <openvdb/tree/LeafManager.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <limits>
#include <unistd.h>

namespace vdbrad {

VoxelIndex::VoxelIndex()
    : mTree(new IndexTree(-1))
{
}

VoxelIndex::VoxelIndex(const openvdb::MaskTree& mask)
{
    // Counted before anything is allocated: a small file can hold an active tile of 4096^3
    // voxels, which densified below would exhaust memory instead of failing.
    checkVoxelCount(mask.activeVoxelCount());
    mTree.reset(new IndexTree(mask, /*inactive=*/-1, /*active=*/0, openvdb::TopologyCopy()));
    // Active tiles would make "one array entry per voxel" ambiguous: densify them first.
    mTree->voxelizeActiveTiles();

    openvdb::tree::LeafManager<IndexTree> leaves(*mTree);
    const size_t leafCount = leaves.leafCount();

    // Serial prefix sum over leaf populations fixes every voxel's array slot, so the parallel
    // fill below is deterministic whatever the thread count.
    mLeafBegin.resize(leafCount + 1);
    mLeafOrigins.resize(leafCount);
    std::vector<size_t> counts(leafCount);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leafCount),
        [&](const tbb::blocked_range<size_t>& r) {
            for (size_t n = r.begin(); n != r.end(); ++n) counts[n] = leaves.leaf(n).onVoxelCount();
        });
    size_t total = 0;
    for (size_t n = 0; n < leafCount; ++n) {
        mLeafBegin[n] = total;
        mLeafOrigins[n] = leaves.leaf(n).origin();
        total += counts[n];
    }
    mLeafBegin[leafCount] = total;

    mCoords.resize(total);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leafCount),
        [&](const tbb::blocked_range<size_t>& r) {
            for (size_t n = r.begin(); n != r.end(); ++n) {
                size_t i = mLeafBegin[n];
                for (auto it = leaves.leaf(n).beginValueOn(); it; ++it, ++i) {
                    it.setValue(int32_t(i));
                    mCoords[i] = it.getCoord();
                }
            }
        });
}

void
VoxelIndex::checkVoxelCount(uint64_t count)
{
    if (count > uint64_t(std::numeric_limits<int32_t>::max())) {
        OPENVDB_THROW(openvdb::ValueError, "too many voxels: " << count << " (at most 2^31 - 1)");
    }
    // The index alone (a coordinate and an int32 slot per voxel) must fit in this machine's
    // memory; its users need several times more.
    const double need = double(count) * double(sizeof(openvdb::Coord) + sizeof(int32_t));
    const double have = physicalMemory();
    if (have > 0.0 && need > have) {
        OPENVDB_THROW(openvdb::ValueError, "too many voxels: " << count << " would need "
            << std::lround(need / double(1 << 30)) << " GiB for their index alone, more than "
            "the " << std::lround(have / double(1 << 30)) << " GiB of memory of this machine");
    }
}

openvdb::CoordBBox
VoxelIndex::bbox() const
{
    openvdb::CoordBBox box;
    mTree->evalActiveVoxelBoundingBox(box);
    return box;
}

} // namespace vdbrad
