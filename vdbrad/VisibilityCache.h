// VisibilityCache: what every voxel sees along each direction, kept from one iteration to the
// next.
//
// Which voxel a voxel sees along a direction (LineSweep::seen) depends on the geometry only, yet
// a line sweep recomputes it every iteration: finding the lines, the visibility rule and the
// line fronts are most of an iteration's cost. Kept, a direction's later iterations are a gather
// along a sequential stream (how much faster: BENCHMARKS.md, "Visibility cache").
//
// Memory: a direction's report is one entry per voxel, delta-coded against the last voxel seen
// (neighbours in visiting order see neighbours): 1 byte for a small step or "sees nothing", 3 for
// a 16-bit step, 5 for an absolute position, so mostly 1 byte per voxel, against 4 for plain
// positions (measured sizes: BENCHMARKS.md, "Visibility cache"). Directions are kept first come,
// first served while the budget lasts; which ones are kept changes the speed, never the result.
#pragma once

#include "vdbrad/LineSweep.h"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

namespace vdbrad {

class VisibilityCache
{
public:
    static constexpr uint32_t kNone = LineSweep::kNone;
    /// Kept directions are replayed together, up to kReplayed at a time (replay()), in blocks of
    /// kReplayBlock voxels: each block takes every queued direction in turn, so that the
    /// block's sums and normals stay in the first-level cache (24 KiB, RGB) while the
    /// directions' reports and seen radiosity stream by. Block and batch sizes: BENCHMARKS.md
    /// ("Blocked replays"); 32 directions keep progress and cancellation prompt.
    static constexpr size_t kReplayed = 32;
    static constexpr uint32_t kReplayBlock = 1024;

    /// @brief An empty cache for @a directions directions over @a voxels voxels, which keeps at
    /// most @a budget bytes of reports.
    VisibilityCache(size_t directions, size_t voxels, size_t budget);

    /// @brief Keep direction @a k's report @a seen (one entry per voxel: the position it sees,
    /// or kNone) if it fits what is left of the budget; returns whether it was kept.
    /// Thread-safe for distinct @a k. @a scratch: memory a thread reuses from one call to the
    /// next (worstBytes()).
    bool offer(size_t k, const uint32_t* seen, std::vector<uint8_t>& scratch);

    bool has(size_t k) const { return bool(mData[k]); }
    size_t voxels() const { return mVoxels; }
    /// Bytes held, and directions kept.
    size_t bytes() const { return mBudget - mLeft.load(); }
    size_t kept() const { return mKept.load(); }

    /// Bytes of the report of a direction with @a voxels voxels, at most.
    static size_t worstBytes(size_t voxels) { return 5 * voxels; }
    /// The same, as memory estimates count it: above the sizes measured on the canonical scenes
    /// (BENCHMARKS.md, "Visibility cache"); what the budget allows is the hard cap.
    static size_t typicalBytes(size_t voxels) { return 2 * voxels; }

    /// Direction k's kept report (has(k) must hold), decoded one voxel at a time in position
    /// order, so that several directions can be replayed in one pass over the voxels.
    class Reader
    {
    public:
        Reader() = default;
        Reader(const VisibilityCache& cache, size_t k) : mNext(cache.mData[k].get()) {}
        /// The next voxel's entry: false if it sees nothing, else true and @a y the voxel it
        /// sees.
        bool next(uint32_t& y)
        {
            const int8_t c = int8_t(*mNext++);
            if (c == kSeesNothing) return false;
            if (c < kStep16) {
                mLast += uint32_t(int32_t(c));
            } else if (c == kStep16) {
                int16_t d;
                std::memcpy(&d, mNext, sizeof d);
                mNext += sizeof d;
                mLast += uint32_t(int32_t(d));
            } else {
                std::memcpy(&mLast, mNext, sizeof mLast);
                mNext += sizeof mLast;
            }
            y = mLast;
            return true;
        }

    private:
        const uint8_t* mNext = nullptr;
        uint32_t mLast = 0;
    };

private:
    // One-byte codes: a step of -127..125 from the last voxel seen, or one of these.
    static constexpr int8_t kSeesNothing = -128;
    static constexpr int8_t kStep16 = 126;      // then an int16 step
    static constexpr int8_t kAbsolute = 127;    // then the uint32 position

    size_t mVoxels, mBudget;
    std::atomic<size_t> mLeft, mKept{0};
    std::vector<std::unique_ptr<uint8_t[]>> mData;
};

/// A report that the cache did not keep (LineSweep::seen()'s array), read entry by entry as
/// VisibilityCache::Reader reads a kept one.
struct RawReport
{
    const uint32_t* at;
    bool next(uint32_t& y)
    {
        y = *at++;
        return y != LineSweep::kNone;
    }
};

/// @brief Gather along @a count (<= kReplayed) directions @a sigma from their reports, read by
/// @a readers: voxel x (a position in @a sweep's order) receives |sigma . n_x| c Bp[y] in G[x]
/// and (if Hits) the weight |sigma . n_x| c in H[x], y the voxel it sees. The terms arrive in the
/// order one sweep per direction gives them, so the sums have its bits.
template<bool Hits, typename ReaderT, typename ValueT, typename AccT, typename ScalarT>
void
replay(const LineSweep& sweep, const openvdb::Coord* sigma, const float* coefficient,
    ReaderT* readers, size_t count, const ValueT* Bp, AccT* G, ScalarT* H, uint32_t n)
{
    // Raw pointers and a block of sigma . n computed in vector lanes, so that the gather loop
    // reloads nothing it could keep in registers (through vectors, it did: the compiler could
    // not prove the sums' stores leave them alone).
    std::array<float, VisibilityCache::kReplayBlock> facing;
    for (uint32_t x0 = 0, x1; x0 < n; x0 = x1) {
        x1 = x0 + std::min(VisibilityCache::kReplayBlock, n - x0);
        for (size_t j = 0; j < count; ++j) {
            sweep.facing(sigma[j], x0, x1, facing.data());
            const float cj = coefficient[j];
            ReaderT reader = readers[j];   // in registers across the block
            for (uint32_t x = x0; x < x1; ++x) {
                uint32_t y;
                if (!reader.next(y)) continue;
                const float w = std::abs(facing[x - x0]) * cj;
                G[x] += Bp[y] * w;
                if constexpr (Hits) H[x] += w;
            }
            readers[j] = reader;
        }
    }
}

} // namespace vdbrad
