// VisibilityCache: what every voxel sees along each direction, kept from one iteration to the
// next.
//
// Which voxel a voxel sees along a direction (LineSweep::seen) depends on the geometry only, yet
// a line sweep recomputes it every iteration: finding the lines, the visibility rule and the
// line fronts are most of an iteration's cost. Kept, a direction's later iterations are a gather
// along a sequential stream (how much faster: docs/journal/2026-11-24-radiosity-solver-speed.md).
//
// Memory: a direction's report is one entry per voxel, delta-coded against the last voxel seen
// (neighbours in visiting order see neighbours), in one of two codes chosen for the whole cache:
//  - bytes (when the budget holds every direction that way): 1 byte for a step of -127..125 or
//    "sees nothing", 3 for a 16-bit step, 5 for an absolute position; ~1.2 bytes per voxel and
//    direction on the canonical scenes, and the fastest to replay;
//  - nibbles (when it does not): 4 bits for "sees nothing" or one of the direction's 12 most
//    frequent steps (a table kept with the report), then escapes with an 8-bit step, a 16-bit
//    step or the absolute position (2, 4 or 8 more nibbles); ~0.8 bytes per voxel and
//    direction, so that the budget keeps ~1.5x as many directions, replayed ~1.4x slower.
// Sizes and speeds: docs/performance.md. Directions are kept first come, first served while the
// budget (or their pool's share of it, pools()) lasts; which ones are kept, and the code, change
// the speed, never the result.
#pragma once

#include "vdbrad/sweep/LineSweep.h"

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
    /// directions' reports and seen radiosity stream by. Block and batch sizes:
    /// docs/journal/2026-11-24-radiosity-solver-speed.md; 32 directions keep progress and
    /// cancellation prompt.
    static constexpr size_t kReplayed = 32;
    static constexpr uint32_t kReplayBlock = 1024;

    /// How reports are coded (the file comment).
    enum class Code { Bytes, Nibbles };

    /// @brief An empty cache for @a directions directions over @a voxels voxels, which keeps at
    /// most @a budget bytes of reports: in bytes if the budget holds every direction at
    /// typicalBytes(voxels, Code::Bytes), else in nibbles (or in @a forced, for tests).
    VisibilityCache(size_t directions, size_t voxels, size_t budget);
    VisibilityCache(size_t directions, size_t voxels, size_t budget, Code forced);
    /// The code the first constructor chooses (memory estimates ask it too).
    static Code codeFor(size_t directions, size_t voxels, size_t budget)
    {
        return budget / std::max<size_t>(directions, 1) >= typicalBytes(voxels, Code::Bytes)
            ? Code::Bytes : Code::Nibbles;
    }

    /// @brief Keep direction @a k's report @a seen (one entry per voxel: the position it sees,
    /// or kNone) if it fits what is left of the budget; returns whether it was kept.
    /// Thread-safe for distinct @a k. @a scratch: memory a thread reuses from one call to the
    /// next (worstBytes()).
    bool offer(size_t k, const uint32_t* seen, std::vector<uint8_t>& scratch);

    /// @brief Split the budget into pools, direction k drawing on pool @a poolOf[k] only, each
    /// pool getting the budget's share of its directions. Before any offer(). Solvers pool the
    /// directions by accumulator group, so that every group keeps its share and the groups'
    /// replays stay as long as each other (first come, first served over the whole budget,
    /// the groups swept first kept everything and the last ones little: on 2 threads 19 % of
    /// the time was spent waiting for them, thesis-size workload). kNoPool: a direction this
    /// cache is never offered (another rank's), which takes no share.
    void pools(const std::vector<uint32_t>& poolOf);
    static constexpr uint32_t kNoPool = UINT32_MAX;

    Code code() const { return mCode; }
    bool has(size_t k) const { return bool(mData[k]); }
    size_t voxels() const { return mVoxels; }
    /// Bytes held, and directions kept.
    size_t bytes() const { return mHeld.load(); }
    size_t kept() const { return mKept.load(); }

    /// Steps a report's table holds (codes 1-12), and the range its candidates come from.
    static constexpr int kTableSteps = 12;
    static constexpr int32_t kTableRange = 2048;   ///< steps in [-kTableRange, kTableRange)
    static constexpr int32_t kUnused = INT32_MIN;  ///< outside that range: never coded
    /// Bytes of the report of a direction with @a voxels voxels, at most (either code, whole
    /// words): 5 per voxel in bytes; the table, then up to 9 nibbles per voxel.
    static size_t worstBytes(size_t voxels)
    {
        const size_t most = std::max(5 * voxels, kHeaderBytes + (9 * voxels + 1) / 2);
        return (most + 3) / 4 * 4;
    }
    /// Per voxel, what worstBytes() grows by, rounded up (memory estimates).
    static constexpr size_t kWorstBytesPerVoxel = 5;
    /// The same, as memory estimates count it: above the sizes measured on the canonical scenes
    /// (docs/performance.md); what the budget allows is the hard cap.
    static size_t typicalBytes(size_t voxels, Code code)
    {
        return code == Code::Bytes ? 2 * voxels : kHeaderBytes + voxels;
    }

    /// @brief The table a report of @a n entries gets: its kTableSteps most frequent steps
    /// (from the last voxel seen, as the code counts them) in [-kTableRange, kTableRange), by
    /// decreasing count, ties to the smaller step; entries no step needs hold kUnused.
    static std::array<int32_t, kTableSteps> table(const uint32_t* seen, size_t n);

    /// Direction k's kept report (has(k) must hold), decoded one voxel at a time in position
    /// order, so that several directions can be replayed in one pass over the voxels:
    /// ByteReader for Code::Bytes, Reader for Code::Nibbles.
    class ByteReader
    {
    public:
        ByteReader() = default;
        ByteReader(const VisibilityCache& cache, size_t k)
            : mNext(reinterpret_cast<const uint8_t*>(cache.mData[k].get())) {}
        /// The next voxel's entry: false if it sees nothing, else true and @a y the voxel it
        /// sees.
        bool next(uint32_t& y)
        {
            const int8_t c = int8_t(*mNext++);
            if (c == kByteSeesNothing) return false;
            if (c < kByteStep16) {
                mLast += uint32_t(int32_t(c));
            } else if (c == kByteStep16) {
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

    class Reader
    {
    public:
        Reader() = default;
        Reader(const VisibilityCache& cache, size_t k)
            : mSteps(cache.mData[k].get())
            , mNext(reinterpret_cast<const uint8_t*>(mSteps + kHeaderWords))
        {
        }
        /// The next voxel's entry: false if it sees nothing, else true and @a y the voxel it
        /// sees.
        bool next(uint32_t& y)
        {
            const uint32_t c = nibble();
            if (c > uint32_t(kTableSteps)) {
                if (c == kStep8) {
                    mLast += uint32_t(int32_t(int8_t(uint8_t(nibbles(2)))));
                } else if (c == kStep16) {
                    mLast += uint32_t(int32_t(int16_t(uint16_t(nibbles(4)))));
                } else {
                    mLast = nibbles(8);
                }
                y = mLast;
                return true;
            }
            // "Sees nothing" (code 0) adds mSteps[0] = 0: no branch for the common codes.
            mLast += mSteps[c];
            y = mLast;
            return c != kSeesNothing;
        }

    private:
        uint32_t nibble()
        {
            const uint32_t v = (uint32_t(*mNext) >> mShift) & 15u;
            mNext += mShift >> 2;   // the high nibble ends its byte
            mShift ^= 4u;
            return v;
        }
        uint32_t nibbles(int count)
        {
            uint32_t v = 0;
            for (int i = 0; i < count; ++i) v |= nibble() << (4 * i);
            return v;
        }

        // Code c -> step (c = 1..12; 0: 0), then the codes: pointers, so that a replay keeps
        // the whole reader in registers.
        const uint32_t* mSteps = nullptr;
        const uint8_t* mNext = nullptr;
        uint32_t mShift = 0;   // 0: the low nibble of *mNext is next, 4: the high one
        uint32_t mLast = 0;
    };

private:
    // One-byte codes: a step of -127..125 from the last voxel seen, or one of these.
    static constexpr int8_t kByteSeesNothing = -128;
    static constexpr int8_t kByteStep16 = 126;     // then an int16 step
    static constexpr int8_t kByteAbsolute = 127;   // then the uint32 position

    size_t encodeBytes(const uint32_t* seen, uint8_t* out) const;
    size_t encodeNibbles(const uint32_t* seen, uint8_t* out) const;

    // 4-bit codes (a table step is its 1-based index).
    static constexpr uint32_t kSeesNothing = 0;
    static constexpr uint32_t kStep8 = 13;      // then an int8 step (2 nibbles, low first)
    static constexpr uint32_t kStep16 = 14;     // then an int16 step (4 nibbles)
    static constexpr uint32_t kAbsolute = 15;   // then the uint32 position (8 nibbles)
    // A report: kHeaderWords words (0, then the table as two's complement), then its codes.
    static constexpr size_t kHeaderWords = 1 + kTableSteps;
    static constexpr size_t kHeaderBytes = kHeaderWords * sizeof(uint32_t);

    size_t mVoxels, mBudget;
    Code mCode;
    std::vector<uint32_t> mPoolOf;                       // empty: one pool
    std::unique_ptr<std::atomic<size_t>[]> mLeft;        // bytes left, per pool
    size_t mPools = 1;
    std::atomic<size_t> mHeld{0}, mKept{0};
    std::vector<std::unique_ptr<uint32_t[]>> mData;   // words, so the table reads as words
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
