#include "vdbrad/distribute/SlabDistribution.h"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <map>

namespace vdbrad {

SlabPartition::SlabPartition(const VoxelIndex& voxels, int slabs)
{
    // Voxels per leaf column x (origins are multiples of 8), in x order.
    std::map<int32_t, size_t> columns;
    for (size_t l = 0; l < voxels.leafCount(); ++l) {
        const size_t end = voxels.leafBegin(l + 1);
        columns[voxels.leafOrigin(l).x()] += end - voxels.leafBegin(l);
    }
    if (slabs < 1 || size_t(slabs) > columns.size()) {
        OPENVDB_THROW(openvdb::ValueError, "the scene is " << columns.size()
            << " leaves (of 8 voxels) wide along x: it can be cut into at most that many "
            "slabs, not " << slabs);
    }
    // Slab s ends at the first column where the running count reaches (s + 1) / slabs of the
    // voxels, leaving at least one column for each slab after it.
    const double total = double(voxels.size());
    size_t seen = 0, c = 0;
    for (const auto& [x, count] : columns) {
        const int s = int(mFirstX.size()) - 1;
        const size_t columnsLeft = columns.size() - c;
        const bool full = s >= 0 && double(seen) >= total * double(s + 1) / double(slabs);
        if (mFirstX.empty() || ((full || columnsLeft == size_t(slabs) - mFirstX.size())
                                   && int(mFirstX.size()) < slabs)) {
            mFirstX.push_back(x);
            mCounts.push_back(0);
        }
        mCounts.back() += count;
        seen += count;
        ++c;
    }
}

int
SlabPartition::slabOf(int32_t x) const
{
    return int(std::upper_bound(mFirstX.begin(), mFirstX.end(), x) - mFirstX.begin()) - 1;
}

std::vector<uint32_t>
SlabPartition::voxelsOf(const VoxelIndex& voxels, int s) const
{
    std::vector<uint32_t> out;
    out.reserve(mCounts[size_t(s)]);
    for (size_t l = 0; l < voxels.leafCount(); ++l) {
        if (slabOf(voxels.leafOrigin(l).x()) != s) continue;
        const size_t end = voxels.leafBegin(l + 1);
        for (size_t i = voxels.leafBegin(l); i < end; ++i) out.push_back(uint32_t(i));
    }
    return out;
}

} // namespace vdbrad
