#include "vdbrad/VisibilityCache.h"

namespace vdbrad {

VisibilityCache::VisibilityCache(size_t directions, size_t voxels, size_t budget)
    : mVoxels(voxels)
    , mBudget(budget)
    , mLeft(budget)
    , mData(directions)
{
}

bool
VisibilityCache::offer(size_t k, const uint32_t* seen, std::vector<uint8_t>& scratch)
{
    scratch.resize(worstBytes(mVoxels));
    uint8_t* out = scratch.data();
    uint32_t last = 0;
    for (size_t x = 0; x < mVoxels; ++x) {
        const uint32_t y = seen[x];
        if (y == kNone) {
            *out++ = uint8_t(kSeesNothing);
            continue;
        }
        const int64_t step = int64_t(y) - int64_t(last);
        last = y;
        if (step >= -127 && step < kStep16) {
            *out++ = uint8_t(int8_t(step));
        } else if (step >= INT16_MIN && step <= INT16_MAX) {
            *out++ = uint8_t(kStep16);
            const int16_t d = int16_t(step);
            std::memcpy(out, &d, sizeof d);
            out += sizeof d;
        } else {
            *out++ = uint8_t(kAbsolute);
            std::memcpy(out, &y, sizeof y);
            out += sizeof y;
        }
    }
    const size_t size = size_t(out - scratch.data());
    size_t left = mLeft.load();
    do {
        if (left < size) return false;
    } while (!mLeft.compare_exchange_weak(left, left - size));
    mData[k].reset(new uint8_t[size]);
    std::memcpy(mData[k].get(), scratch.data(), size);
    ++mKept;
    return true;
}

} // namespace vdbrad
