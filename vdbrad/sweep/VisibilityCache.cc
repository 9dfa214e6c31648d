#include "vdbrad/sweep/VisibilityCache.h"

#include <algorithm>

namespace vdbrad {

VisibilityCache::VisibilityCache(size_t directions, size_t voxels, size_t budget)
    : VisibilityCache(directions, voxels, budget, codeFor(directions, voxels, budget))
{
}

VisibilityCache::VisibilityCache(size_t directions, size_t voxels, size_t budget, Code forced)
    : mVoxels(voxels)
    , mBudget(budget)
    , mCode(forced)
    , mLeft(new std::atomic<size_t>[1])
    , mData(directions)
{
    mLeft[0].store(budget);
}

void
VisibilityCache::pools(const std::vector<uint32_t>& poolOf)
{
    if (poolOf.size() != mData.size()) {
        OPENVDB_THROW(openvdb::ValueError, "VisibilityCache::pools needs one pool per direction");
    }
    size_t count = 0, pooled = 0;
    for (uint32_t p : poolOf) {
        if (p != kNoPool) count = std::max(count, size_t(p) + 1);
    }
    std::vector<size_t> directions(count, 0);
    for (uint32_t p : poolOf) {
        if (p != kNoPool) { ++directions[p]; ++pooled; }
    }
    // Directions in no pool draw on an empty last one.
    mPoolOf = poolOf;
    for (uint32_t& p : mPoolOf) {
        if (p == kNoPool) p = uint32_t(count);
    }
    mPools = count + 1;
    mLeft.reset(new std::atomic<size_t>[mPools]);
    // Each pool its directions' share, rounded down (the budget is never exceeded).
    const long double perDirection = pooled == 0 ? 0.0L
        : static_cast<long double>(mBudget) / static_cast<long double>(pooled);
    for (size_t p = 0; p < count; ++p) {
        mLeft[p].store(size_t(perDirection * static_cast<long double>(directions[p])));
    }
    mLeft[count].store(0);
}

std::array<int32_t, VisibilityCache::kTableSteps>
VisibilityCache::table(const uint32_t* seen, size_t n)
{
    std::vector<uint32_t> counts(size_t(2 * kTableRange), 0);
    uint32_t last = 0;
    for (size_t x = 0; x < n; ++x) {
        if (seen[x] == kNone) continue;
        const int64_t step = int64_t(seen[x]) - int64_t(last);
        last = seen[x];
        if (step >= -kTableRange && step < kTableRange) ++counts[size_t(step + kTableRange)];
    }
    // The most frequent first; ties to the smaller step (the lower bucket).
    std::array<int32_t, kTableSteps> steps;
    steps.fill(kUnused);
    std::array<uint32_t, kTableSteps> best{};
    for (size_t b = 0; b < counts.size(); ++b) {
        const uint32_t c = counts[b];
        if (c == 0 || c <= best[kTableSteps - 1]) continue;
        int i = kTableSteps - 1;
        for (; i > 0 && best[size_t(i - 1)] < c; --i) {
            best[size_t(i)] = best[size_t(i - 1)];
            steps[size_t(i)] = steps[size_t(i - 1)];
        }
        best[size_t(i)] = c;
        steps[size_t(i)] = int32_t(b) - kTableRange;
    }
    return steps;
}

size_t
VisibilityCache::encodeBytes(const uint32_t* seen, uint8_t* begin) const
{
    uint8_t* out = begin;
    uint32_t last = 0;
    for (size_t x = 0; x < mVoxels; ++x) {
        const uint32_t y = seen[x];
        if (y == kNone) {
            *out++ = uint8_t(kByteSeesNothing);
            continue;
        }
        const int64_t step = int64_t(y) - int64_t(last);
        last = y;
        if (step >= -127 && step < kByteStep16) {
            *out++ = uint8_t(int8_t(step));
        } else if (step >= INT16_MIN && step <= INT16_MAX) {
            *out++ = uint8_t(kByteStep16);
            const int16_t d = int16_t(step);
            std::memcpy(out, &d, sizeof d);
            out += sizeof d;
        } else {
            *out++ = uint8_t(kByteAbsolute);
            std::memcpy(out, &y, sizeof y);
            out += sizeof y;
        }
    }
    return size_t(out - begin);
}

size_t
VisibilityCache::encodeNibbles(const uint32_t* seen, uint8_t* begin) const
{
    const std::array<int32_t, kTableSteps> steps = table(seen, mVoxels);
    // Step -> code for the table's steps (0: not in it).
    std::array<uint8_t, size_t(2 * kTableRange)> codeOf{};
    for (int c = 0; c < kTableSteps; ++c) {
        const int32_t step = steps[size_t(c)];
        if (step != kUnused) codeOf[size_t(step + kTableRange)] = uint8_t(c + 1);
    }
    // Word 0 stays 0 (begin is zeroed): the step of code 0.
    for (size_t c = 0; c < size_t(kTableSteps); ++c) {
        const uint32_t word = uint32_t(steps[c]);
        std::memcpy(begin + (c + 1) * sizeof word, &word, sizeof word);
    }
    uint8_t* out = begin + kHeaderBytes;
    uint32_t shift = 0;
    auto put = [&](uint32_t v, int count) {
        for (int i = 0; i < count; ++i, v >>= 4) {
            *out |= uint8_t((v & 15u) << shift);
            out += shift >> 2;
            shift ^= 4u;
        }
    };
    uint32_t last = 0;
    for (size_t x = 0; x < mVoxels; ++x) {
        const uint32_t y = seen[x];
        if (y == kNone) {
            put(kSeesNothing, 1);
            continue;
        }
        const int64_t step = int64_t(y) - int64_t(last);
        last = y;
        const uint32_t code = step >= -kTableRange && step < kTableRange
            ? codeOf[size_t(step + kTableRange)] : 0u;
        if (code != 0) {
            put(code, 1);
        } else if (step >= INT8_MIN && step <= INT8_MAX) {
            put(kStep8, 1);
            put(uint32_t(uint8_t(int8_t(step))), 2);
        } else if (step >= INT16_MIN && step <= INT16_MAX) {
            put(kStep16, 1);
            put(uint32_t(uint16_t(int16_t(step))), 4);
        } else {
            put(kAbsolute, 1);
            put(y, 8);
        }
    }
    if (shift != 0) ++out;   // a half-used last byte
    return size_t(out - begin);
}

bool
VisibilityCache::offer(size_t k, const uint32_t* seen, std::vector<uint8_t>& scratch)
{
    scratch.assign(worstBytes(mVoxels), 0);
    const size_t used = mCode == Code::Bytes ? encodeBytes(seen, scratch.data())
                                             : encodeNibbles(seen, scratch.data());
    // Whole words: the bytes held, as the budget counts them.
    const size_t words = (used + 3) / 4, size = words * 4;
    std::atomic<size_t>& pool = mLeft[mPoolOf.empty() ? 0 : mPoolOf[k]];
    size_t left = pool.load();
    do {
        if (left < size) return false;
    } while (!pool.compare_exchange_weak(left, left - size));
    mData[k].reset(new uint32_t[words]);
    std::memcpy(mData[k].get(), scratch.data(), size);
    mHeld += size;
    ++mKept;
    return true;
}

} // namespace vdbrad
