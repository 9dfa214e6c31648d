#include "vdbrad/sweep/LeafOrder.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

namespace vdbrad {

LeafOrder::Signs
LeafOrder::baseSigns(const openvdb::Coord& sigma, bool& reversed)
{
    Signs s = {sigma.x() < 0 ? -1 : 1, sigma.y() < 0 ? -1 : 1, sigma.z() < 0 ? -1 : 1};
    reversed = sigma.x() < 0;
    if (reversed) s = {-s[0], -s[1], -s[2]};
    return s;
}

LeafOrder::LeafOrder(const VoxelIndex& index, const Signs& signs)
    : mSigns(signs)
{
    for (int s : signs) {
        if (s != 1 && s != -1) OPENVDB_THROW(openvdb::ValueError, "LeafOrder signs must be +-1");
    }
    const size_t leafCount = index.leafCount();
    mLeaves.resize(leafCount);
    for (size_t n = 0; n < leafCount; ++n) mLeaves[n] = uint32_t(n);
    auto key = [&](uint32_t n) {
        const openvdb::Coord& o = index.leafOrigin(n);
        return openvdb::Coord(signs[0] * o.x(), signs[1] * o.y(), signs[2] * o.z());
    };
    tbb::parallel_sort(mLeaves.begin(), mLeaves.end(),
        [&](uint32_t a, uint32_t b) { return key(a) < key(b); });

    // Where each leaf's voxels start in the visiting order.
    std::vector<size_t> start(leafCount + 1, 0);
    for (size_t k = 0; k < leafCount; ++k) {
        const uint32_t n = mLeaves[k];
        start[k + 1] = start[k] + (index.leafBegin(n + 1) - index.leafBegin(n));
    }
    const int mask = (signs[0] < 0 ? 7 << 6 : 0) | (signs[1] < 0 ? 7 << 3 : 0)
        | (signs[2] < 0 ? 7 : 0);
    mOrder.resize(index.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leafCount),
        [&](const tbb::blocked_range<size_t>& r) {
            // A 512-slot table per leaf: a counting sort on the flipped offset.
            std::array<int32_t, 512> slot;
            for (size_t k = r.begin(); k != r.end(); ++k) {
                const uint32_t n = mLeaves[k];
                slot.fill(-1);
                for (size_t i = index.leafBegin(n); i < index.leafBegin(n + 1); ++i) {
                    const openvdb::Coord& c = index.coord(i);
                    const int offset = ((c.x() & 7) << 6) | ((c.y() & 7) << 3) | (c.z() & 7);
                    slot[size_t(offset ^ mask)] = int32_t(i);
                }
                size_t out = start[k];
                for (int32_t i : slot) {
                    if (i >= 0) mOrder[out++] = uint32_t(i);
                }
            }
        });
}

} // namespace vdbrad
