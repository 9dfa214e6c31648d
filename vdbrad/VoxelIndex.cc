#include "vdbrad/VoxelIndex.h"

#include <openvdb/tree/LeafManager.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <limits>

namespace vdbrad {

VoxelIndex::VoxelIndex()
    : mTree(new IndexTree(-1))
{
}

VoxelIndex::VoxelIndex(const openvdb::MaskTree& mask)
    : mTree(new IndexTree(mask, /*inactive=*/-1, /*active=*/0, openvdb::TopologyCopy()))
{
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
    if (total > size_t(std::numeric_limits<int32_t>::max())) {
        OPENVDB_THROW(openvdb::ValueError, "too many voxels: " << total << " (at most 2^31 - 1)");
    }

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

openvdb::CoordBBox
VoxelIndex::bbox() const
{
    openvdb::CoordBBox box;
    mTree->evalActiveVoxelBoundingBox(box);
    return box;
}

} // namespace vdbrad
