// SlabDistribution: one scene's voxels spread over the ranks of an MPI job, by slabs along x,
// with the line fronts passed between neighbouring ranks (thesis §6.2.2.3: spatial blocks and
// line frontiers).
//
// Why slabs of leaves along x: every sweep visits the voxels in a LeafOrder whose base pattern
// has x >= 0, and that order sorts the leaves by x first. So the voxels of a slab of whole leaves,
// x0 <= leaf origin x < x1, are one contiguous range of every pattern's order, and the slabs
// follow each other in it: a pass along a pattern's order over the whole scene is the pass over
// slab 0, then slab 1, ..., each starting with the line fronts the one before it left
// (LineSweep::slabPass()); a pass against the order runs the chain the other way. Each rank
// keeps its slab only (its voxels' layouts, iterate, sums: what grows with the scene), and what
// crosses a boundary is one record per line that still carries light there.
//
// The chain makes one pass of one direction sequential over the ranks, so the ranks work on
// different accumulator groups (SweepSchedule.h) at once, a pipeline: each group runs its
// directions in order (ascending pass, then descending), so that every voxel adds its
// directions' light in the serial tool's order and the result is the serial tool's, bit for
// bit. A rank runs whichever group's next pass has its input, on one thread: run one rank per
// core. With G groups in flight and K ranks, a direction's round trip is 2K - 1 slab passes of
// which each rank does two, so the ranks are kept busy while G >= K
// (docs/journal/2026-12-05-slab-distribution.md).
#pragma once

#include "vdbrad/core/VoxelIndex.h"
#include "vdbrad/distribute/Distribution.h"

#include <chrono>
#include <cstdint>
#include <thread>
#include <utility>
#include <vector>

namespace vdbrad {

class SlabPartition
{
public:
    /// @brief Cut @a voxels into @a slabs slabs of whole leaves along x, of nearly equal voxel
    /// counts (leaf columns are not split, so a slab may hold up to one column more).
    /// @throw openvdb::ValueError if there are fewer leaf columns along x than slabs
    SlabPartition(const VoxelIndex& voxels, int slabs);

    int slabs() const { return int(mFirstX.size()); }
    /// The slab of a leaf whose origin's x is @a x.
    int slabOf(int32_t x) const;
    /// The voxels of slab @a s (VoxelIndex numbering, increasing).
    std::vector<uint32_t> voxelsOf(const VoxelIndex& voxels, int s) const;
    /// Voxels of each slab.
    const std::vector<size_t>& counts() const { return mCounts; }

private:
    std::vector<int32_t> mFirstX;   // per slab, the smallest leaf origin x it holds
    std::vector<size_t> mCounts;
};

/// Runs the accumulator groups' passes over this rank's slab, each with the fronts of its
/// neighbour's pass (see the file comment), exchanging them through a Distribution.
class SlabPipeline
{
public:
    explicit SlabPipeline(const Distribution& ranks) : mRanks(ranks) {}

    /// @brief For each (group g, directions d) of @a groups: pass(g, j, ascending, in, out)
    /// for j = 0 .. d - 1, ascending then descending, each pass once its input @a in (the
    /// bytes its neighbour's pass left: the previous rank's for an ascending pass, the next
    /// one's for a descending one; empty at the chain's start) has arrived; @a out goes to
    /// the neighbour on the other side. Groups are interleaved as their inputs arrive; a
    /// group's passes keep their order. Returns when this rank's passes are done and its
    /// messages delivered. The time spent waiting for input counts in the Distribution's
    /// exchangeSeconds().
    /// @throw whatever @a pass or @a check throws (check() is called between passes)
    template<typename PassT, typename CheckT>
    void run(const std::vector<std::pair<int, size_t>>& groups, PassT&& pass, CheckT&& check)
    {
        const int r = mRanks.rank(), K = mRanks.ranks();
        std::vector<size_t> next(groups.size(), 0);   // pass number: 2j + descending
        size_t left = 0;
        for (const auto& gd : groups) left += 2 * gd.second;
        std::vector<char> in, out;
        auto idle = std::chrono::microseconds(1);
        while (left > 0) {
            bool moved = false;
            for (size_t e = 0; e < groups.size(); ++e) {
                const int g = groups[e].first;
                if (next[e] == 2 * groups[e].second) continue;
                const bool ascending = next[e] % 2 == 0;
                const int from = ascending ? r - 1 : r + 1, to = ascending ? r + 1 : r - 1;
                const int tag = 2 * g + (ascending ? 0 : 1);
                in.clear();
                if (from >= 0 && from < K && !mRanks.receive(from, tag, in)) continue;
                check();
                out.clear();
                pass(g, next[e] / 2, ascending, in, out);
                if (to >= 0 && to < K) mRanks.send(to, tag, std::move(out));
                ++next[e];
                --left;
                moved = true;
            }
            if (moved) {
                idle = std::chrono::microseconds(1);
                continue;
            }
            // Nothing has its input yet: wait without taking a core from the ranks that work.
            const auto t0 = std::chrono::steady_clock::now();
            std::this_thread::sleep_for(idle);
            if (idle < std::chrono::microseconds(256)) idle *= 2;
            mRanks.waited(seconds(t0));
            check();
        }
        const auto t0 = std::chrono::steady_clock::now();
        mRanks.finishSends();
        mRanks.waited(seconds(t0));
    }

private:
    static double seconds(std::chrono::steady_clock::time_point t0)
    {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    }
    const Distribution& mRanks;
};

} // namespace vdbrad
