// SweepSchedule: how every solver sweeps the directions of a DirectionSet (thesis §4.3.3.4).
//
// A direction sigma is served by the visiting order (LeafOrder) whose signs match its own: a
// pattern and its negation give reverse orders, so four base patterns serve every direction,
// forwards or backwards. The schedule deals the directions to those patterns, lays the voxels
// out in each pattern's order (LineSweep: coordinates, normals, regions read sequentially by a
// sweep) and deals the directions again to a fixed number of accumulator groups:
//
//     group g  ->  pattern g % 4, its directions j = g / 4, g / 4 + 2, g / 4 + 4, ...
//
// Each group sweeps its directions one after the other, on one thread, into its own accumulator
// (in its pattern's order); the accumulators are then added voxel by voxel in group order
// (sum()). The groups do not depend on the thread count, so neither do the results, bit for bit.
// Groups 0-3 and 4-7 each hold half of every pattern's directions: the two halves of an in-place
// (block Gauss-Seidel) iteration.
//
// What a line carries, what a voxel does with it and how the sums update the iterate are the
// solvers' own (RadiositySolver: radiosity between surface voxels; CloudTransfer: radiance
// through a medium); this file is everything else they share.
#pragma once

#include "vdbrad/core/Denormals.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/core/VoxelIndex.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/sweep/DirectionSet.h"
#include "vdbrad/sweep/LeafOrder.h"
#include "vdbrad/sweep/LinePartition.h"
#include "vdbrad/sweep/LineSweep.h"

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <array>
#include <atomic>
#include <memory>
#include <string>
#include <vector>

namespace vdbrad {

/// Finished directions of an iteration, for the interrupter's percentage, and whether it asked
/// to stop. Shared by the groups' threads.
class SweepProgress
{
public:
    /// @param total  directions the iteration sweeps (100 %)
    SweepProgress(openvdb::util::NullInterrupter* interrupt, size_t total)
        : mInterrupt(interrupt), mTotal(total > 0 ? total : 1) {}
    /// @a count more directions are done; asks the interrupter whether to stop.
    void finished(size_t count)
    {
        const size_t done = mDone += count;
        if (mInterrupt && mInterrupt->wasInterrupted(int(100 * done / mTotal))) mCancelled = true;
    }
    /// True once the interrupter asked to stop: a group stops before its next direction.
    bool cancelled() const { return mCancelled.load(std::memory_order_relaxed); }

private:
    openvdb::util::NullInterrupter* mInterrupt;
    size_t mTotal;
    std::atomic<size_t> mDone{0};
    std::atomic<bool> mCancelled{false};
};

class SweepSchedule
{
public:
    /// Accumulator groups: fixed, so that results do not depend on the thread count.
    static constexpr int kGroups = 8;
    static constexpr int kPatterns = 4;
    static_assert(kGroups % kPatterns == 0, "groups are dealt to the sign patterns");

    /// Scratch memory each thread keeps from one direction and iteration to the next (a fresh
    /// one per group and iteration reallocates and faults in its pages every time).
    template<typename T> using PerThread = tbb::enumerable_thread_specific<T>;

    /// The voxels in the visiting order of one base sign pattern, with the directions it serves.
    struct Pattern
    {
        LeafOrder::Signs signs{};
        std::vector<size_t> directions;     ///< direction indices, in set order
        std::vector<uint32_t> order;        ///< position -> voxel (VoxelIndex numbering)
        std::vector<uint32_t> position;     ///< voxel -> position
        std::unique_ptr<LineSweep> sweep;   ///< the layout a sweep reads (null: no sweeps)
        bool empty() const { return directions.empty(); }
    };

    /// How the patterns' LineSweep layouts are built (LineSweep's constructor).
    struct Layout
    {
        bool sweeps = true;                                  ///< false: orders only
        LineType lines = LineType::Naive;
        const std::vector<openvdb::Vec3f>* normals = nullptr;   ///< surfaces; null: a medium
        float depth = 1.f;                                   ///< occlusion depth, voxels
        const std::vector<uint32_t>* regions = nullptr;      ///< air regions; null: one
        const LineSweep::Frame* frame = nullptr;   ///< a slab's whole scene (LineSweep::setFrame)
    };

    /// @brief Deal @a directions to the patterns and lay out @a voxels in each used pattern's
    /// order (@a voxels must outlive nothing: the layouts are copies).
    SweepSchedule(const VoxelIndex& voxels, DirectionSet directions, const Layout& layout);

    const DirectionSet& directions() const { return mDirections; }
    size_t voxelCount() const { return mVoxels; }
    const Pattern& pattern(size_t p) const { return mPatterns[p]; }
    /// The pattern group @a g sweeps in.
    static size_t patternOf(int g) { return size_t(g % kPatterns); }
    const Pattern& patternOfGroup(int g) const { return mPatterns[patternOf(g)]; }
    /// Whether direction @a k is swept backwards along its pattern's order.
    bool reversed(size_t k) const { return mReversed[k] != 0; }
    /// f(k) for the directions of group @a g, in order.
    template<typename F> void forDirections(int g, F&& f) const
    {
        const std::vector<size_t>& dirs = patternOfGroup(g).directions;
        for (size_t j = size_t(g / kPatterns); j < dirs.size(); j += kGroups / kPatterns) {
            f(dirs[j]);
        }
    }

    /// @brief body(g) for every group whose pattern serves a direction and for which
    /// @a selected(g) holds, in parallel (one task per group), with denormals flushed to zero
    /// (Denormals.h).
    /// @throw vdbrad::Cancelled(@a what) if @a progress was cancelled
    template<typename SelectT, typename BodyT>
    void forEachGroup(const SweepProgress& progress, const char* what, SelectT&& selected,
        BodyT&& body) const;

    /// @brief One round of an iteration, as every solver runs it: this rank sweeps the groups
    /// @a inRound(g) selects that it owns (forEachGroup(), @a sweep(g)), then each of those
    /// groups' results reaches every rank from its owner (@a share(g, owner), which hands the
    /// group's arrays to Distribution::share(); not called alone). Every rank then holds every
    /// group, and sum() adds them in group order as one process does: the same bits for any
    /// number of ranks and threads.
    /// @throw vdbrad::Cancelled(@a what) if @a progress was cancelled
    template<typename InRoundT, typename SweepT, typename ShareT>
    void round(const SweepProgress& progress, const char* what, const Distribution& ranks,
        InRoundT&& inRound, SweepT&& sweep, ShareT&& share) const;

    /// @brief @a out[k * width + c] = @a in[order[k] * width + c]: per-voxel values (@a width
    /// each) in pattern @a p's order, so that a sweep reads them sequentially.
    template<typename T>
    void toPatternOrder(size_t p, const std::vector<T>& in, std::vector<T>& out,
        size_t width = 1) const;

    /// Directions of the groups @a selected(g) (e.g. a rank's, Distribution.h).
    template<typename SelectT> size_t directionsOf(SelectT&& selected) const
    {
        size_t count = 0;
        for (int g = 0; g < kGroups; ++g) {
            if (selected(g)) forDirections(g, [&](size_t) { ++count; });
        }
        return count;
    }

    /// @brief Add @a width values of voxel @a i from each group's accumulator (in its pattern's
    /// order; an empty one is skipped) to @a out, in group order, as WideT.
    template<typename WideT, typename ArraysT>
    void sum(const ArraysT& accumulators, size_t i, size_t width, WideT* out) const
    {
        for (int g = 0; g < kGroups; ++g) {
            const auto& a = accumulators[size_t(g)];
            if (a.empty()) continue;
            const size_t at = size_t(patternOfGroup(g).position[i]) * width;
            for (size_t c = 0; c < width; ++c) out[c] += WideT(a[at + c]);
        }
    }

    /// Bytes the schedule holds per voxel (orders, positions, the layouts' copies).
    static size_t bytesPerVoxel(bool sweeps, bool normals, bool regions);

private:
    DirectionSet mDirections;
    size_t mVoxels = 0;
    std::array<Pattern, kPatterns> mPatterns;
    std::vector<char> mReversed;
};

template<typename SelectT, typename BodyT>
void
SweepSchedule::forEachGroup(const SweepProgress& progress, const char* what, SelectT&& selected,
    BodyT&& body) const
{
    tbb::parallel_for(tbb::blocked_range<int>(0, kGroups, 1),
        [&](const tbb::blocked_range<int>& r) {
            const ScopedFlushDenormals flush;
            for (int g = r.begin(); g != r.end(); ++g) {
                if (patternOfGroup(g).empty() || !selected(g)) continue;
                body(g);
            }
        });
    if (progress.cancelled()) throw Cancelled(what);
}

template<typename InRoundT, typename SweepT, typename ShareT>
void
SweepSchedule::round(const SweepProgress& progress, const char* what, const Distribution& ranks,
    InRoundT&& inRound, SweepT&& sweep, ShareT&& share) const
{
    forEachGroup(progress, what, [&](int g) { return inRound(g) && ranks.owns(g); }, sweep);
    if (!ranks.distributed()) return;
    for (int g = 0; g < kGroups; ++g) {
        if (inRound(g) && !patternOfGroup(g).empty()) share(g, ranks.ownerOf(g));
    }
}

template<typename T>
void
SweepSchedule::toPatternOrder(size_t p, const std::vector<T>& in, std::vector<T>& out,
    size_t width) const
{
    const std::vector<uint32_t>& order = mPatterns[p].order;
    out.resize(order.size() * width);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, order.size()),
        [&](const tbb::blocked_range<size_t>& r) {
            for (size_t k = r.begin(); k != r.end(); ++k) {
                const T* from = &in[size_t(order[k]) * width];
                for (size_t c = 0; c < width; ++c) out[k * width + c] = from[c];
            }
        });
}

} // namespace vdbrad
