// LineSweep: who sees whom along the digital lines of one direction (thesis §4.3.3).
//
// For a direction sigma, every surface voxel lies on one digital line (LinePartition). Visiting
// the voxels in a LeafOrder whose signs match sigma meets the voxels of every line in their order
// along the line, so a single streaming pass that keeps, per line, only the last voxel met (the
// "frontier") finds every pair of consecutive voxels: no line lists, no sorting. The pass in
// reverse order serves -sigma.
//
// Visibility rule, for light travelling along t (t = sigma on the forward pass, -sigma on the
// backward one), with d(v) = t . n_v:
//   - a sender (d > 0: its front faces along t) replaces what travels on the line: the next
//     voxels see it;
//   - a receiver (d < 0: its front faces the incoming light) sees what travels on the line and
//     lets it pass, so that the neighbours of a flat wall, which digital lines at grazing angles
//     run through one after the other, do not hide each other; the same holds for d = 0;
//   - but a receiver x that lies behind the surface of the receiver p met just before it,
//     (c_x - c_p) . n_p <= -depth, is hidden by p's solid: it sees nothing (p's back is black).
//     That is what stops light at one-voxel walls: behind a wall voxel that lets light pass,
//     the next voxel is a sender (the wall's other side replaces the light) or lies behind the
//     wall's plane. `depth` (voxels, default 1) keeps the digitisation noise of one surface
//     (voxel centres scatter up to ~0.87 voxel around a curved or tilted plane) from hiding its
//     own neighbours.
//   - light passes only between voxels that face the same air region (Enclosure.h), so a ray
//     leaving a room through the corner voxel it starts from reaches nothing outside.
// Each receiver is reported once per direction with the voxel it sees, or none (the open sky, or
// a back).
//
// Layout: a LineSweep holds the voxels of one LeafOrder sign pattern laid out in that visiting
// order (coordinates, normals, regions), so that a sweep reads everything sequentially; voxels
// are named by their position in that order.
//
// The ordered walk itself (walk(): every line in both senses, in exact line order, with a state
// per line) knows nothing of surfaces; the cloud's transfer sweeps (CloudTransfer.h) use it with
// radiance as the state.
#pragma once

#include "vdbrad/core/VoxelIndex.h"
#include "vdbrad/sweep/LeafOrder.h"
#include "vdbrad/sweep/LinePartition.h"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>
#include <unordered_map>
#include <vector>

namespace vdbrad {

class LineSweep
{
public:
    static constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

    /// @brief The voxels of @a index in the visiting order @a order.
    /// @param normals  index-space unit normals, one per voxel of @a index (surfaces: sweep());
    ///                 null for a medium, which only walk()s its lines
    /// @param depth    occlusion depth in voxels (see the file comment), > 0
    /// @param regions  per voxel of @a index, the air region it faces (Enclosure.h); null: one
    LineSweep(const VoxelIndex& index, const LeafOrder& order,
        const std::vector<openvdb::Vec3f>* normals, LineType lines, float depth = 1.f,
        const std::vector<uint32_t>* regions = nullptr)
        : mSigns(order.signs()), mLines(lines), mDepth(depth)
    {
        const std::vector<uint32_t>& seq = order.voxels();
        mCoords.resize(seq.size());
        if (normals) mNormals.resize(seq.size());
        if (regions) mRegions.resize(seq.size());
        for (size_t k = 0; k < seq.size(); ++k) {
            mCoords[k] = index.coord(seq[k]);
            if (normals) mNormals[k] = (*normals)[seq[k]];
            if (regions) mRegions[k] = (*regions)[seq[k]];
        }
        const openvdb::CoordBBox box = index.bbox();
        mMin = box.min();
        mMax = box.max();
        mLowX = mMin.x();
        mHighX = mMax.x();
        mFrameVoxels = seq.size();
    }

    /// The box whose lines are keyed and numbered (the partition is centred on it) and the
    /// voxel count that decides whether they are numbered densely: by default the voxels' own
    /// bounding box and count; a whole scene's where this sweep holds one slab of it
    /// (SlabDistribution.h), so that every slab keys every line alike.
    struct Frame
    {
        openvdb::CoordBBox box;
        size_t voxels = 0;
    };
    void setFrame(const Frame& frame)
    {
        mMin = frame.box.min();
        mMax = frame.box.max();
        mFrameVoxels = frame.voxels;
    }

    size_t size() const { return mCoords.size(); }
    const LeafOrder::Signs& signs() const { return mSigns; }
    /// Coordinate of the voxel at position @a x of this sweep's order.
    const openvdb::Coord& coord(uint32_t x) const { return mCoords[x]; }

    /// What a line carries to the next voxel: the last voxel met (its position, top bit set if
    /// it was a sender), 1 + the region of the voxel a receiver sees (0: it sees nothing) and a
    /// payload of that voxel, copied when it was met (its radiosity, for the solver), so that
    /// receivers never reach back to a voxel visited long ago. All zero bytes when nothing has
    /// been met (`last` is read only when `open` is not 0), so that a pass clears its lines with
    /// a memset.
    template<typename PayloadT>
    struct Front
    {
        uint32_t last = 0;
        uint32_t open = 0;
        PayloadT payload{};
    };

    /// Per-thread scratch memory, reused from one direction to the next; StateT is what each
    /// line carries from voxel to voxel.
    template<typename StateT>
    struct Lanes
    {
        std::vector<uint32_t> slots;     // line slot of each voxel, by position in the order
        // Bubbles (standard lines): pairs (k, k') of consecutive voxels of one line met in the
        // wrong order (k < k' in visiting order, k' first along the line), sorted by k' and by k.
        std::vector<std::pair<uint32_t, uint32_t>> bubblesByLater, bubblesByEarlier;
        std::vector<uint32_t> lastOnLine;                    // scratch for finding them
        std::vector<StateT> fronts;
        std::unordered_map<LineKey, uint32_t, LineKeyHash> ids;   // sparse scenes only
        std::vector<float> facing;       // sigma . n of each voxel, by position (sweep())
        // How assignLines() numbered the lines: densely, slot = (i - i0) * nj + (j - j0), or
        // on first sight (ids); and their count. Slab passes map keys to slots with these.
        bool dense = true;
        int64_t i0 = 0, j0 = 0, nj = 1;
        size_t lines = 0;
        int major = 0;                   // the partition's major axis
        // Slab passes: the last voxels of lines that came from the previous slab, met before
        // any voxel of this one (numbered from size() on), for the occlusion test.
        std::vector<openvdb::Coord> ghostCoords;
        std::vector<openvdb::Vec3f> ghostNormals;
        std::vector<LineKey> keyOfSlot;  // sparse numbering: each slot's key
        std::vector<uint32_t> crossed;   // the slots of a pass's incoming lines
        std::vector<uint32_t> leaving;   // ... and of its leaving ones
    };
    template<typename PayloadT>
    using Workspace = Lanes<Front<PayloadT>>;

    /// @brief Walk every line of sigma in both senses, in exact line order: first along +sigma
    /// (@a forward true), then along -sigma, calling step(x, state, forward) for every voxel x
    /// (a position in this sweep's order) with the state its line carries, which each pass
    /// starts as StateT() and step() updates. endOfPass(fronts, lines, forward) then sees every
    /// line's final state (what leaves the last voxel): fronts[0, lines). Sequential, like
    /// sweep().
    template<typename StateT, typename StepT, typename EndT>
    void walk(const openvdb::Coord& sigma, bool reversed, Lanes<StateT>& work, StepT&& step,
        EndT&& endOfPass) const
    {
        const size_t n = mCoords.size();
        const size_t lines = assignLines(sigma, reversed, work);
        auto along = [&](size_t k) { return uint32_t(reversed ? n - 1 - k : k); };
        for (const bool forward : {true, false}) {
            clear(work.fronts, lines);
            // Bubbles: each pass skips the voxel of a pair it meets first and visits it right
            // after its partner. Cursors count pairs from the pass's start.
            const auto& skips = forward ? work.bubblesByEarlier : work.bubblesByLater;
            const auto& replays = forward ? work.bubblesByLater : work.bubblesByEarlier;
            auto nth = [&](const auto& pairs, size_t i) -> const std::pair<uint32_t, uint32_t>& {
                return pairs[forward ? i : pairs.size() - 1 - i];
            };
            // Compiled twice, so that bubble-free passes (all naive ones) carry no cursor tests.
            auto pass = [&](auto repair) {
                size_t skip = 0, replay = 0;
                for (size_t m = 0; m < n; ++m) {
                    const size_t k = forward ? m : n - 1 - m;
                    if constexpr (decltype(repair)::value) {
                        if (skip < skips.size()) {
                            const auto& b = nth(skips, skip);
                            if ((forward ? b.first : b.second) == k) { ++skip; continue; }
                        }
                    }
                    const uint32_t x = along(k);
                    step(x, work.fronts[work.slots[x]], forward);
                    if constexpr (decltype(repair)::value) {
                        if (replay < replays.size()) {
                            const auto& b = nth(replays, replay);
                            if ((forward ? b.second : b.first) == k) {
                                ++replay;
                                const uint32_t held = along(forward ? b.first : b.second);
                                step(held, work.fronts[work.slots[held]], forward);
                            }
                        }
                    }
                }
            };
            if (skips.empty()) pass(std::false_type());
            else pass(std::true_type());
            endOfPass(static_cast<const StateT*>(work.fronts.data()), lines, forward);
        }
    }

    /// @brief Report, for every voxel x that faces sigma or -sigma, what it sees:
    /// visit(x, seen, sigmaDotN) with x a position in this sweep's order, seen a pointer to
    /// load(y) for the voxel y it sees (null if it sees nothing) and sigmaDotN = sigma . n_x
    /// (> 0: x looks along +sigma, < 0: along -sigma). load(k) is called once per sender and
    /// pass, in visiting order. Sequential: run one direction per thread, each thread with its
    /// own @a work.
    /// @param reversed  as returned by LeafOrder::baseSigns(sigma, reversed), whose signs must
    ///                  be this sweep's
    template<typename PayloadT, typename LoadT, typename VisitT>
    void sweep(const openvdb::Coord& sigma, bool reversed, Workspace<PayloadT>& work,
        LoadT&& load, VisitT&& visit) const
    {
        facing(sigma, work.facing);
        auto run = [&](auto hasRegions) {
            walk(sigma, reversed, work,
                [&](uint32_t x, Front<PayloadT>& front, bool forward) {
                    const float travel = forward ? 1.f : -1.f;
                    this->step<decltype(hasRegions)::value>(x, front, work.facing[x] * travel,
                        travel, load, visit);
                },
                [](const Front<PayloadT>*, size_t, bool) {});
        };
        withRegions(run);
    }

    /// @brief sweep()'s report as an array: out[x] = the position of the voxel that x sees,
    /// kNone where it sees nothing or faces neither sense (sigma . n_x = 0). What a voxel sees
    /// depends on the geometry only, so that a solver can keep @a out (VisibilityCache) instead
    /// of sweeping sigma again. @a out holds size() entries.
    void seen(const openvdb::Coord& sigma, bool reversed, Workspace<uint32_t>& work,
        uint32_t* out) const
    {
        std::fill_n(out, size(), kNone);
        sweep(sigma, reversed, work, [](uint32_t y) { return y; },
            [&](uint32_t x, const uint32_t* y, float) { if (y) out[x] = *y; });
    }

    /// out[x - begin] = sigma . n_x for the positions x in [begin, end), bit for bit as
    /// sweep() reports them (the same vector kernel, dotAll() in LineSweep.cc).
    void facing(const openvdb::Coord& sigma, uint32_t begin, uint32_t end, float* out) const;

    /// @brief Number sigma's lines and compute every voxel's facing, once per direction before
    /// its two slabPass()es. Naive lines only (a standard line's bubble may straddle two
    /// slabs).
    template<typename PayloadT>
    void prepareSlab(const openvdb::Coord& sigma, bool reversed, Workspace<PayloadT>& work) const
    {
        if (mLines != LineType::Naive) {
            OPENVDB_THROW(openvdb::ValueError, "slab passes need naive lines");
        }
        facing(sigma, work.facing);
        assignLines(sigma, reversed, work);
        if (!work.dense) {
            work.keyOfSlot.assign(work.lines, LineKey());
            for (const auto& [key, slot] : work.ids) work.keyOfSlot[slot] = key;
        }
    }

    /// @brief One of sweep()'s two passes over this sweep's voxels, a slab of a larger scene
    /// whose frame (setFrame()) they share: along this sweep's order (@a ascending, positions
    /// 0 to size() - 1) or against it. Lines start from what the pass over the neighbouring
    /// slab before this one left, @a in (@a inBytes bytes; none for the first slab), instead of
    /// empty; @a out receives every line that still carries light at the end. Chained over the
    /// slabs in order (against it for !ascending), the passes report exactly what sweep()
    /// reports over the whole scene (tests/test_radiosity.cc). prepareSlab() first.
    ///
    /// @a fronts: the lines' state during the pass, which may be shared by workspaces whose
    /// passes do not overlap. It must come empty, or as a slabPass() left it: a pass reads
    /// only the lines its voxels or @a in name, and leaves every line empty (open = 0, which a
    /// step treats as no light at all), so that it never clears the whole frame's lines,
    /// which outnumber a slab's voxels.
    ///
    /// What crosses, per line that carries light: the line (its dense slot, 4 bytes, which
    /// every slab of one frame numbers alike, or its key where lines are numbered on first
    /// sight), its region + 1 with the sender bit, and the payload; where the last voxel met
    /// let the light pass, also that voxel's coordinate and normal, which the next voxel's
    /// occlusion test reads (a "ghost", numbered from size() on in this pass), unless no voxel
    /// past the boundary can see it (Beyond).
    template<typename PayloadT, typename LoadT, typename VisitT>
    void slabPass(const openvdb::Coord& sigma, bool reversed, bool ascending,
        Workspace<PayloadT>& work, std::vector<Front<PayloadT>>& fronts, const char* in,
        size_t inBytes, std::vector<char>& out, LoadT&& load, VisitT&& visit) const
    {
        static_assert(std::is_trivially_copyable_v<PayloadT>, "payloads travel as bytes");
        const size_t n = mCoords.size();
        // Along +sigma when the order's sense is sigma's.
        const bool forward = ascending != reversed;
        const float travel = forward ? 1.f : -1.f;
        // Sparse numbering: lines an earlier pass brought through have slots past `lines`.
        const size_t live = work.dense ? work.lines : work.keyOfSlot.size();
        if (fronts.size() < live) fronts.resize(live);
        work.ghostCoords.clear();
        work.ghostNormals.clear();
        const size_t lineBytes = work.dense ? sizeof(uint32_t) : sizeof(LineKey);
        const size_t record = lineBytes + sizeof(uint32_t) + sizeof(PayloadT);
        constexpr size_t kGhost = sizeof(uint32_t) + sizeof(openvdb::Coord)
            + sizeof(openvdb::Vec3f);
        auto slotOf = [&](const char* line) -> uint32_t {
            if (work.dense) return read<uint32_t>(line);
            // A line with no voxel here still passes through: it gets a slot of its own.
            const LineKey key = read<LineKey>(line);
            const auto [it, added] = work.ids.emplace(key, uint32_t(work.keyOfSlot.size()));
            if (added) {
                work.keyOfSlot.push_back(key);
                if (fronts.size() < work.keyOfSlot.size()) fronts.resize(work.keyOfSlot.size());
            }
            return it->second;
        };
        std::vector<uint32_t>& crossed = work.crossed;
        crossed.clear();
        if (inBytes > 0) {
            const uint64_t count = read<uint64_t>(in), ghosts = read<uint64_t>(in + 8);
            const char* at = in + 16;
            crossed.resize(count);
            for (uint64_t e = 0; e < count; ++e, at += record) {
                crossed[e] = slotOf(at);
                Front<PayloadT>& f = fronts[crossed[e]];
                f.open = read<uint32_t>(at + lineBytes);
                f.last = f.open & kSender;
                f.open &= ~kSender;
                f.payload = read<PayloadT>(at + lineBytes + sizeof(uint32_t));
            }
            for (uint64_t e = 0; e < ghosts; ++e, at += kGhost) {
                Front<PayloadT>& f = fronts[crossed[read<uint32_t>(at)]];
                f.last = uint32_t(n + work.ghostCoords.size());
                work.ghostCoords.push_back(read<openvdb::Coord>(at + sizeof(uint32_t)));
                work.ghostNormals.push_back(
                    read<openvdb::Vec3f>(at + sizeof(uint32_t) + sizeof(openvdb::Coord)));
            }
        }
        auto run = [&](auto hasRegions) {
            constexpr bool kRegions = decltype(hasRegions)::value;
            for (size_t m = 0; m < n; ++m) {
                const uint32_t x = uint32_t(ascending ? m : n - 1 - m);
                step<kRegions, true>(x, fronts[work.slots[x]], work.facing[x] * travel, travel,
                    load, visit, &work);
            }
        };
        withRegions(run);
        // What leaves: the lines that carry light (unless Beyond says nothing past the
        // boundary sees it), then the ghosts of those whose last voxel let it pass. Only the
        // lines this pass named can carry light; each is emptied once looked at.
        std::vector<uint32_t>& leaving = work.leaving;
        leaving.clear();
        uint64_t ghosts = 0;
        const Beyond beyond(sigma, work.major, travel,
            ascending ? (mHighX & ~7) + 8 : (mLowX & ~7) - 1, mDepth);
        auto look = [&](uint32_t slot) {
            Front<PayloadT>& f = fronts[slot];
            if (f.open == 0 || (f.open & kSender)) return;   // nothing travels, or listed
            // With sigma.x = 0 a line keeps its x, so none leaves this slab.
            bool leaves = sigma.x() != 0;
            if (leaves && !(f.last & kSender)) {
                const bool local = f.last < n;
                leaves = !beyond.hidden(local ? mCoords[f.last] : work.ghostCoords[f.last - n],
                    local ? mNormals[f.last] : work.ghostNormals[f.last - n]);
                if (leaves) ++ghosts;
            }
            if (leaves) {
                leaving.push_back(slot);
                // Kept open until written (below), with a mark that it is listed.
                f.open |= kSender;
            } else {
                f.open = 0;
            }
        };
        for (size_t x = 0; x < n; ++x) look(work.slots[x]);
        for (const uint32_t slot : crossed) look(slot);
        const uint64_t count = leaving.size();
        out.resize(count == 0 ? 0 : 16 + count * record + ghosts * kGhost);
        if (count == 0) return;
        char* at = out.data();
        char* ghost = at + 16 + count * record;
        write(at, count);
        write(at + 8, ghosts);
        at += 16;
        for (uint32_t e = 0; e < count; ++e, at += record) {
            const uint32_t slot = leaving[e];
            Front<PayloadT>& f = fronts[slot];
            if (work.dense) {
                write(at, slot);
            } else {
                write(at, work.keyOfSlot[slot]);
            }
            write(at + lineBytes, uint32_t((f.open & ~kSender) | (f.last & kSender)));
            write(at + lineBytes + sizeof(uint32_t), f.payload);
            if (!(f.last & kSender)) {
                write(ghost, e);
                write(ghost + sizeof(uint32_t),
                    f.last < n ? mCoords[f.last] : work.ghostCoords[f.last - n]);
                write(ghost + sizeof(uint32_t) + sizeof(openvdb::Coord),
                    f.last < n ? mNormals[f.last] : work.ghostNormals[f.last - n]);
                ghost += kGhost;
            }
            f.open = 0;
        }
    }

    /// @brief The same report as sweep(), built the way the thesis does (§6.2.1.1): a stable
    /// counting sort of the voxels into explicit per-line lists, then each list walked in both
    /// senses. Kept to measure against the streaming sweep
    /// (docs/journal/2026-11-24-radiosity-solver-speed.md), which needs no lists.
    template<typename PayloadT, typename LoadT, typename VisitT>
    void sweepLists(const openvdb::Coord& sigma, bool reversed, Workspace<PayloadT>& work,
        std::vector<uint32_t>& starts, std::vector<uint32_t>& listed, LoadT&& load,
        VisitT&& visit) const
    {
        const size_t n = mCoords.size();
        const size_t lines = assignLines(sigma, reversed, work);
        auto along = [&](size_t k) { return uint32_t(reversed ? n - 1 - k : k); };
        starts.assign(lines + 1, 0);
        for (size_t k = 0; k < n; ++k) ++starts[work.slots[k] + 1];
        for (size_t l = 0; l < lines; ++l) starts[l + 1] += starts[l];
        listed.resize(n);
        {
            std::vector<uint32_t> fill(starts.begin(), starts.end() - 1);
            for (size_t k = 0; k < n; ++k) {
                const uint32_t x = along(k);
                listed[fill[work.slots[x]]++] = x;
            }
        }
        facing(sigma, work.facing);
        if (mLines == LineType::Standard) {
            // The exact line order, bubbles included (the counting sort kept the visiting order).
            const LinePartition partition(sigma, mLines);
            for (size_t l = 0; l < lines; ++l) {
                std::sort(listed.begin() + starts[l], listed.begin() + starts[l + 1],
                    [&](uint32_t a, uint32_t b) {
                        return partition.position(mCoords[a]) < partition.position(mCoords[b]);
                    });
            }
        }
        auto run = [&](auto hasRegions) {
            constexpr bool kRegions = decltype(hasRegions)::value;
            for (size_t l = 0; l < lines; ++l) {
                Front<PayloadT> forward, backward;
                for (uint32_t e = starts[l]; e < starts[l + 1]; ++e) {
                    step<kRegions>(listed[e], forward, work.facing[listed[e]], 1.f, load, visit);
                }
                for (uint32_t e = starts[l + 1]; e > starts[l]; --e) {
                    const uint32_t x = listed[e - 1];
                    step<kRegions>(x, backward, -work.facing[x], -1.f, load, visit);
                }
            }
        };
        withRegions(run);
    }

private:
    static constexpr uint32_t kSender = 0x80000000u;   // positions are < 2^31 (VoxelIndex)

    /// Whether a line whose last voxel p let the light pass can still show p's light to a
    /// voxel past a slab's boundary x = @a boundary (the first x a later slab may hold,
    /// ascending; the last one, descending). On a naive line of sigma (major axis m) a later
    /// voxel x lies at c_x - c_p = k t / |sigma_m| + e, k >= 0 the steps along m, t the travel
    /// direction and |e_i| < 1 on the two other axes. So (c_x - c_p) . n_p, which the
    /// occlusion test compares with -depth, is below k (t . n_p) / |sigma_m| + |n_i| + |n_j|,
    /// and k is at least what reaching the boundary takes. Where that bound is <= -depth
    /// (with a margin for float rounding), every voxel past the boundary is hidden from p:
    /// the line then carries what an empty one does, and need not be sent. (Through a
    /// one-voxel wall, light goes on past the wall's receivers: most of the lines leaving a
    /// slab of a closed room; docs/journal/2026-12-05-slab-distribution.md.)
    struct Beyond
    {
        /// @param major  the partition's major axis (LinePartition::majorAxis(): with equal
        ///               components, the one its forms are written for)
        Beyond(const openvdb::Coord& sigma, int major, float travel, int32_t boundary,
            float depth)
            : boundary(boundary), m(major)
        {
            const double along = std::abs(double(sigma[m]));
            for (int a = 0; a < 3; ++a) t[a] = double(travel) * sigma[a] / along;
            // Steps along m per voxel of x, and the part of a voxel x may stray by.
            perX = m == 0 || sigma.x() == 0 ? 1.0 : along / std::abs(double(sigma.x()));
            stray = m == 0 ? 0.0 : 1.0;
            limit = -double(depth) - 1e-3;
        }
        inline bool hidden(const openvdb::Coord& p, const openvdb::Vec3f& normal) const
        {
            const double tn = t[0] * normal[0] + t[1] * normal[1] + t[2] * normal[2];
            if (!(tn < 0.0)) return false;
            const double steps = (std::abs(double(boundary) - double(p.x())) - stray) * perX;
            const double spread = double(std::abs(normal[0])) + std::abs(normal[1])
                + std::abs(normal[2]) - std::abs(normal[m]);
            return steps > 0.0 && steps * tn + spread <= limit - 1e-6 * steps;
        }
        int32_t boundary;
        int m;
        double t[3];                // the travel direction per step along m
        double perX, stray, limit;
    };

    // Unaligned reads and writes of a slab message's fields.
    template<typename T> static T read(const char* at)
    {
        T v;
        std::memcpy(static_cast<void*>(&v), at, sizeof(T));
        return v;
    }
    template<typename T> static void write(char* at, const T& v)
    {
        std::memcpy(at, static_cast<const void*>(&v), sizeof(T));
    }

    template<typename T> struct IsFront : std::false_type {};
    template<typename P> struct IsFront<Front<P>> : std::true_type {};

    /// The first @a lines of @a fronts set to the default state StateT(): by memset for a
    /// Front, whose default is zero bytes (element by element was a visible share of a sweep:
    /// docs/journal/2026-11-24-radiosity-solver-speed.md). The vector only grows: resizing it to
    /// each direction's line count initialised its tail twice and, on growth, faulted in fresh
    /// pages.
    template<typename StateT>
    static void clear(std::vector<StateT>& fronts, size_t lines)
    {
        if (fronts.size() < lines) {
            fronts.clear();   // nothing to copy across a reallocation
            fronts.resize(lines);
            return;
        }
        if constexpr (IsFront<StateT>::value) {
            static_assert(std::is_trivially_copyable_v<StateT>, "a Front is cleared by memset");
            if (lines > 0) {
                std::memset(static_cast<void*>(fronts.data()), 0, lines * sizeof(StateT));
            }
        } else {
            std::fill_n(fronts.begin(), lines, StateT());
        }
    }

    /// f(std::true_type()) if voxels face several air regions, else f(std::false_type()): the
    /// step's HasRegions flag.
    template<typename F>
    void withRegions(F&& f) const
    {
        if (mRegions.empty()) f(std::false_type());
        else f(std::true_type());
    }

    /// facing[x] = sigma . n_x for every position x, in vector lanes (LineSweep.cc). The
    /// backward pass's -facing[x] is (-sigma) . n_x bit for bit: negation commutes with rounding.
    void facing(const openvdb::Coord& sigma, std::vector<float>& facing) const;

    /// Fill work.slots (the line of the voxel at each position) and return the number of lines.
    template<typename StateT>
    size_t assignLines(const openvdb::Coord& sigma, bool reversed, Lanes<StateT>& work) const
    {
        LinePartition partition(sigma, mLines);
        // Centred on the scene so that a symmetric scene gets symmetric lines.
        partition.centreOn(mMin + mMax);
        const size_t n = mCoords.size();
        work.slots.resize(n);

        // Line slots, in visiting order along +sigma: dense over the lines crossing the bounding
        // box when those are not much more numerous than the voxels, numbered on first sight
        // otherwise (a few small objects far apart).
        int64_t i0 = std::numeric_limits<int64_t>::max(), i1 = std::numeric_limits<int64_t>::min();
        int64_t j0 = i0, j1 = i1;
        for (int c = 0; c < 8; ++c) {
            const openvdb::Coord corner(c & 1 ? mMax.x() : mMin.x(), c & 2 ? mMax.y() : mMin.y(),
                c & 4 ? mMax.z() : mMin.z());
            const LineKey k = partition.key(corner);
            i0 = std::min(i0, k.i); i1 = std::max(i1, k.i);
            j0 = std::min(j0, k.j); j1 = std::max(j1, k.j);
        }
        const double dense = double(i1 - i0 + 1) * double(j1 - j0 + 1);
        size_t lines = 0;
        // Position of the k-th voxel along +sigma.
        auto along = [&](size_t k) { return uint32_t(reversed ? n - 1 - k : k); };
        const bool isDense = dense <= 4.0 * double(std::max(n, mFrameVoxels)) + 65536.0
            && dense < 4294967296.0;
        const int64_t nj = j1 - j0 + 1;
        auto fill = [&](auto&& keyOf) {
            if (isDense) {
                lines = size_t(dense);
                for (size_t x = 0; x < n; ++x) {
                    const LineKey key = keyOf(mCoords[x]);
                    work.slots[x] = uint32_t((key.i - i0) * nj + (key.j - j0));
                }
            } else {
                // Numbered in visiting order (any numbering would do; this one is reproducible).
                work.ids.clear();
                for (size_t k = 0; k < n; ++k) {
                    const uint32_t x = along(k);
                    const LineKey key = keyOf(mCoords[x]);
                    work.slots[x] = work.ids.emplace(key, uint32_t(work.ids.size())).first->second;
                }
                lines = work.ids.size();
            }
        };
        // Division-free keys (the hottest arithmetic of a sweep) wherever the box allows them,
        // vectorised where it is small enough for 32-bit lanes.
        const LinePartition::BoxKeys boxKeys(partition, openvdb::CoordBBox(mMin, mMax));
        if (isDense && boxKeys.slots(mCoords.data(), n, i0, j0, nj, work.slots.data())) {
            lines = size_t(dense);
        } else if (boxKeys.valid()) {
            fill([&](const openvdb::Coord& c) { return boxKeys.key(c); });
        } else {
            fill([&](const openvdb::Coord& c) { return partition.key(c); });
        }

        // Bubbles (thesis §4.3.3.5): on a standard line, the two middle voxels of a 2x2 block
        // (LinePartition.h) are incomparable, so the visiting order may meet them in either
        // order; only those pairs can be inverted (tests/test_leaforder.cc). Each inversion is
        // repaired in the passes by holding the voxel met first back until its partner, the
        // line's next voxel, has been visited: both passes then follow the exact line order.
        work.bubblesByLater.clear();
        if (mLines == LineType::Standard) {
            work.lastOnLine.assign(lines, kNone);
            for (size_t k = 0; k < n; ++k) {
                uint32_t& last = work.lastOnLine[work.slots[along(k)]];
                if (last != kNone && partition.position(mCoords[along(k)])
                        < partition.position(mCoords[along(last)])) {
                    work.bubblesByLater.emplace_back(last, uint32_t(k));
                }
                last = uint32_t(k);
            }
        }
        work.bubblesByEarlier = work.bubblesByLater;
        std::sort(work.bubblesByEarlier.begin(), work.bubblesByEarlier.end());
        work.dense = isDense;
        work.major = partition.majorAxis();
        work.i0 = i0;
        work.j0 = j0;
        work.nj = nj;
        work.lines = lines;
        return lines;
    }

    /// Visit voxel x, which faces the light by @a dx = t . n_x, with the frontier @a front of
    /// its line, light travelling along t = travel * sigma. HasRegions: mRegions is not empty
    /// (a template flag, so that the one-region case tests nothing per voxel). Ghosts: `last`
    /// may name a voxel of the previous slab (>= size(), in @a ghosts; slabPass()).
    template<bool HasRegions, bool Ghosts = false, typename PayloadT, typename LoadT,
        typename VisitT, typename LanesT = void>
    void step(uint32_t x, Front<PayloadT>& front, float dx, float travel, LoadT& load,
        VisitT& visit, const LanesT* ghosts = nullptr) const
    {
        const uint32_t open = (HasRegions ? mRegions[x] : 0u) + 1u;
        if (dx > 0.f) {
            // A sender replaces what travels, whatever it would have seen.
            front.last = x | kSender;
            front.open = open;
            front.payload = load(x);
            return;
        }
        bool sees = front.open == open;   // 0 (nothing travels) never equals a region + 1
        if (sees && !(front.last & kSender)) {
            // The previous voxel let the light pass: x is hidden if it lies behind it.
            const uint32_t last = front.last;
            bool hidden;
            if constexpr (Ghosts) {
                const size_t n = mCoords.size();
                const openvdb::Coord& c = last < n ? mCoords[last] : ghosts->ghostCoords[last - n];
                const openvdb::Vec3f& nl = last < n ? mNormals[last]
                                                    : ghosts->ghostNormals[last - n];
                hidden = (mCoords[x] - c).asVec3s().dot(nl) <= -mDepth;
            } else {
                (void)ghosts;
                hidden = (mCoords[x] - mCoords[last]).asVec3s().dot(mNormals[last]) <= -mDepth;
            }
            if (hidden) sees = false;
        }
        if (dx < 0.f) visit(x, sees ? &front.payload : nullptr, dx * travel);   // = sigma . n_x
        front.last = x;
        if (!sees) front.open = 0;
    }

    LeafOrder::Signs mSigns;
    std::vector<openvdb::Coord> mCoords;
    std::vector<openvdb::Vec3f> mNormals;
    std::vector<uint32_t> mRegions;
    LineType mLines;
    float mDepth;
    openvdb::Coord mMin, mMax;
    size_t mFrameVoxels = 0;
    int32_t mLowX = 0, mHighX = 0;   // the voxels' own x extent (a frame may be wider)
};

} // namespace vdbrad
