// Distribution: one solve spread over the processes of an MPI job (thesis §6.2.1.2, direction
// subsets).
//
// The sweeps' accumulator groups (SweepSchedule.h: eight, each a fixed share of the directions,
// summed per voxel in group order) are dealt to the ranks, group g to rank g mod K: each rank
// sweeps its groups with its own threads, then every group's accumulator is broadcast from its
// owner, once per half-iteration (the in-place update's phases hold groups 0-3 and 4-7, so two
// ranks get two groups of each). Every rank then holds every group and sums them in group order,
// exactly as one process does: the result is the serial tool's, bit for bit, for any number of
// ranks and threads. Every rank keeps the whole scene and the iterate; what moves per
// half-iteration is (K - 1) / K of four groups' per-voxel sums per rank. (The data distribution
// of §6.2.2, each rank with one slab of the scene, is SlabDistribution.h; it passes line fronts
// from rank to rank with send() and receive().) Per-voxel work that depends on the voxel alone (the
// exact direct light) is shared out in blocks (ownsBlock) and combined by a sum in which one rank's
// value meets the others' zeros (combine): exact too.
//
// The host creates the job's context (join(), once, in main() or at module import) and hands it
// to the solves through their options (`ranks`); the library keeps no global and never starts
// MPI itself. A solve given none, a default-constructed Distribution, a build without MPI (CMake
// found none, or -DVDBRAD_MPI=OFF) or a process not started by mpirun is one process: nothing is
// exchanged.
#pragma once

#include <cstddef>
#include <memory>
#include <vector>

namespace vdbrad {

class Distribution
{
public:
    /// One process: what a solve given no Distribution runs on.
    Distribution();
    Distribution(const Distribution&) = delete;
    Distribution& operator=(const Distribution&) = delete;

    /// @brief The job's processes (MPI_COMM_WORLD), MPI initialised here if this process was
    /// started by mpirun (Open MPI, MPICH or PMIx environment), else one process. For hosts:
    /// call it once per process, from the main thread before any other thread runs, keep the
    /// object while solves run and finalize() it at the end.
    /// @throw openvdb::RuntimeError if MPI was already initialised (a second join())
    static std::unique_ptr<Distribution> join();

    /// @a ranks, or @a alone where it is null: the ranks a solve given @a ranks runs on.
    static const Distribution& orAlone(const Distribution* ranks, const Distribution& alone)
    {
        return ranks ? *ranks : alone;
    }

    int rank() const { return mRank; }
    int ranks() const { return mRanks; }
    bool distributed() const { return mRanks > 1; }
    /// The ranks on this machine (sharing its memory), this one included: 1 alone.
    int localRanks() const { return mLocalRanks; }
    /// The rank that sweeps accumulator group @a g.
    int ownerOf(int g) const { return g % mRanks; }
    bool owns(int g) const { return ownerOf(g) == mRank; }

    /// @brief Every rank gets @a owner's @a bytes at @a data (a broadcast; a no-op alone).
    void share(void* data, size_t bytes, int owner) const;
    /// @brief @a values resized to @a count and given @a owner's values.
    template<typename T>
    void share(std::vector<T>& values, size_t count, int owner) const
    {
        values.resize(count);
        share(values.data(), count * sizeof(T), owner);
    }
    /// @brief @a values summed over the ranks, in place, where at most one rank holds a
    /// value other than 0 in each (so the sum is that value, exactly).
    void combine(std::vector<double>& values) const;
    void combine(float* values, size_t count) const;
    /// @brief Whether this rank computes block @a b of a per-voxel loop that the ranks share
    /// out in blocks (dealt round-robin, so that each gets every part of the scene).
    bool ownsBlock(size_t b) const { return int(b % size_t(mRanks)) == mRank; }
    /// The sum of @a value over the ranks.
    double sum(double value) const;

    /// The largest @a value over the ranks.
    double maximum(double value) const;

    /// @brief Point to point, for passing data along a chain of ranks (SlabDistribution.h):
    /// send @a bytes to rank @a to with @a tag without waiting (kept until delivered);
    /// receive() takes the next message from @a from with @a tag into @a bytes if one has
    /// arrived (false if none has); finishSends() waits until every sent message is
    /// delivered. Messages between two ranks with one tag arrive in the order sent.
    /// @throw openvdb::ValueError for a message of 2 GiB or more
    void send(int to, int tag, std::vector<char>&& bytes) const;
    bool receive(int from, int tag, std::vector<char>& bytes) const;
    void finishSends() const;
    /// @brief Every rank's @a bytes, on rank @a root (one vector per rank; empty elsewhere).
    std::vector<std::vector<char>> gather(const void* data, size_t bytes, int root) const;

    /// What this rank's exchanges have moved (bytes received or sent, as a broadcast's root)
    /// and the seconds it spent in them (waiting for slower ranks included).
    size_t exchangedBytes() const { return mBytes; }
    double exchangeSeconds() const { return mSeconds; }
    /// Count @a seconds this rank spent waiting for another's data in exchangeSeconds().
    void waited(double seconds) const { mSeconds += seconds; }

    /// @brief End the job now, all ranks, with exit status @a code (MPI_Abort; std::exit
    /// alone).
    [[noreturn]] void abort(int code) const;
    /// MPI_Finalize, once, if MPI was initialised (at the end of main()).
    void finalize();

    ~Distribution();

private:
    struct Sends;   // messages on their way (MPI requests and their buffers)
    mutable std::unique_ptr<Sends> mSends;
    int mRank = 0, mRanks = 1, mLocalRanks = 1;
    bool mInitialised = false;
    mutable size_t mBytes = 0;
    mutable double mSeconds = 0.0;
};

} // namespace vdbrad
