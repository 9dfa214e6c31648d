#include "vdbrad/sweep/SweepSchedule.h"

#include <utility>

namespace vdbrad {

SweepSchedule::SweepSchedule(const VoxelIndex& voxels, DirectionSet directions,
    const Layout& layout)
    : mDirections(std::move(directions))
    , mVoxels(voxels.size())
{
    LeafOrder::Patterns dealt = LeafOrder::patterns(mDirections.size(),
        [&](size_t k) { return mDirections.direction(k); });
    mReversed = std::move(dealt.reversed);
    const size_t n = voxels.size();
    for (size_t p = 0; p < size_t(kPatterns); ++p) {
        Pattern& pattern = mPatterns[p];
        pattern.signs = dealt.signs[p];
        pattern.directions = std::move(dealt.directions[p]);
        if (pattern.directions.empty()) continue;
        const LeafOrder order(voxels, pattern.signs);
        pattern.order = order.voxels();
        pattern.position.resize(n);
        for (size_t k = 0; k < n; ++k) pattern.position[pattern.order[k]] = uint32_t(k);
        if (layout.sweeps) {
            pattern.sweep.reset(new LineSweep(voxels, order, layout.normals, layout.lines,
                layout.depth, layout.regions));
            if (layout.frame) pattern.sweep->setFrame(*layout.frame);
        }
    }
}

size_t
SweepSchedule::bytesPerVoxel(bool sweeps, bool normals, bool regions)
{
    // Per pattern: order and position (u32 each), and the sweep's coordinates, normals and
    // regions in that order.
    size_t perPattern = 4 + 4;
    if (sweeps) perPattern += 12 + (normals ? 12 : 0) + (regions ? 4 : 0);
    return size_t(kPatterns) * perPattern;
}

} // namespace vdbrad
