// PeriodicBoundary: the side faces of a cloud's box, across which light wraps around the period
// (CloudTransfer with CloudTransferOptions::periodic; thesis §6.3 solves open boxes only).
//
// Light leaving a side face re-enters through the opposite one at the same height. Lines of a
// direction are not invariant under the period shifts in general, so the re-entering radiance is
// the power that left that face in that voxel layer, shared among the lines entering in that
// layer: exact for horizontally uniform media (slabs), energy-conserving always. The layer is
// that of the midpoint of the digital step that crosses the face (not of a voxel centre projected
// along the direction, which sits up to half a voxel off the line's axis and, along steep
// directions, moves the light several layers per wrap).
//
// Exactly horizontal directions (sigma_up = 0) never rise at all, but each stands for a cell of
// the sphere that spans elevations up to beta = sqrt(Omega) / 2 either way, whose light would
// leave the slab: kept in its layer, it would wrap until it interacts. Their wrapped light is
// followed as two half cells, each re-entering tan(beta / 2) x the box's mean chord layers
// higher (upper half) or lower, split between the two nearest layers; what drifts past the top
// or bottom has left.
//
// Slots: per direction, a slice of 2 senses x 6 faces x layers entries, slot
// (sense * 6 + face) * layers + layer, face = 2 * axis + (0 low, 1 high).
#pragma once

#include "vdbrad/cloud/VoxelStep.h"
#include "vdbrad/sweep/DirectionSet.h"
#include "vdbrad/sweep/LinePartition.h"
#include "vdbrad/sweep/SweepSchedule.h"

#include <openvdb/openvdb.h>

#include <array>
#include <cstdint>
#include <vector>

namespace vdbrad {

class PeriodicBoundary
{
public:
    /// Wrap-around passes per direction and iteration before the rest of the wrapping light is
    /// carried over to the next iteration.
    static constexpr int kMaxWraps = 64;
    /// Light re-entering a layer that no line of its direction enters goes to the nearest layer
    /// within this many that one does (further, it would move light across the box).
    static constexpr int kNeighbourLayers = 1;

    /// @brief The side faces of @a box (index space), @a up the vertical axis, the medium
    /// swept in the plane of the other axes along the @a flat ones (sweptLine()); counts the
    /// lines of every direction of @a schedule entering through each face and layer (a walk per
    /// direction: geometry only).
    PeriodicBoundary(const openvdb::CoordBBox& box, int up, const SweepSchedule& schedule,
        const FlatAxes& flat = FlatAxes{});

    /// @brief The horizontal axes along which a periodic box of @a dim voxels is one voxel
    /// deep: its medium repeats every voxel along them, so it is swept in the plane of the
    /// other axes (sweptLine()), exactly and without copies.
    static FlatAxes flatAxes(const openvdb::Coord& dim, int up);

    /// @brief How many copies of a box of @a dim voxels to solve side by side along each axis
    /// (CloudTransferOptions::minPeriod): along each horizontal axis narrower than
    /// @a minPeriod voxels (-1: ceil(sqrt(directions) / 2)), enough to be that wide, and with
    /// -1 no more than make one period 8 mean optical depths wide (@a depth: the box's mean
    /// optical depth per voxel; light crossing such a period horizontally is gone). None along
    /// flat axes (flatAxes()).
    static openvdb::Coord copies(const openvdb::Coord& dim, int up, int minPeriod,
        size_t directions, double depth);

    int layers() const { return mLayers; }
    /// Entries of one direction's slice, and where direction @a d's starts.
    size_t sliceSize() const { return size_t(2 * 6 * mLayers); }
    size_t slice(size_t d) const { return d * sliceSize(); }
    /// Entries of every direction's slices.
    size_t size() const { return mEnterCount.size(); }
    /// Lines of direction d entering through slot e: mEnterCount[slice(d) + e].
    uint32_t enterCount(size_t d, size_t e) const { return mEnterCount[slice(d) + e]; }

    /// The partition of direction @a sigma's naive lines, centred on the box, that the slots'
    /// digital steps are found with.
    LinePartition partition(const openvdb::Coord& sigma) const;
    /// @brief Slots where the line whose first voxel is @a first enters, and where the line
    /// whose last voxel is @a last leaves, travelling along @a t (the pass's sense, @a forward);
    /// -1: through the top or bottom. By the digital step where there is one, else by
    /// projecting the voxel centre.
    int entering(const LinePartition& part, const openvdb::Coord& sigma,
        const openvdb::Coord& first, const openvdb::Vec3d& t, bool forward) const;
    int leaving(const LinePartition& part, const openvdb::Coord& sigma,
        const openvdb::Coord& last, const openvdb::Vec3d& t, bool forward) const;

    /// Layers a horizontal direction's half cells drift per wrap (0 for other directions).
    double rise(const DirectionSet& directions, size_t d) const;
    /// The flat axes the lines are swept across (sweptLine()).
    const FlatAxes& flat() const { return mFlat; }

    /// @brief What left the side faces (@a exits, one slice of direction @a d, times @a share)
    /// enters through the opposite faces: added to @a into (in a neighbouring layer where no
    /// line enters its own: kNeighbourLayers); what no line enters, or what drifts (@a drift:
    /// +1 upper half cell, -1 lower, 0 none; by @a rise layers) past the top or bottom, has
    /// left the box: added to @a escaped (0 down, 1 up; @a upward: the
    /// direction's up component). Returns the power that wraps.
    double wrap(size_t d, const std::vector<double>& exits, double share, int drift, double rise,
        double upward, std::vector<double>& into, std::array<double, 2>& escaped) const;

    /// @brief The sky's light entering the side faces of horizontal direction @a d (@a rise
    /// > 0) in its sources pass: a half cell drifting up re-enters its lowest layers from below
    /// the box, one drifting down its highest from above (wrap() feeds the others), so those
    /// layers take the sky's @a radiance (per sense) over their lines' @a etendue, added to
    /// @a entry (one slice). Returns the power added.
    double skyDrift(size_t d, double rise, const std::array<float, 2>& radiance, double etendue,
        std::vector<double>& entry) const;

    /// @brief After a pass of direction @a d with its sources: follow the light wrapping around
    /// the period at once, pass after pass (@a pass(), which sweeps with @a entry as the light
    /// entering the side faces and fills @a exits), until what still wraps is negligible, and
    /// write the rest to @a carried (one slice), for the next iteration. A horizontal
    /// direction's two half cells wrap separately, so that each keeps drifting its own way.
    template<typename PassT>
    void followWraps(size_t d, double rise, double upward, std::vector<double>& entry,
        const std::vector<double>& exits, PassT&& pass, double* carried,
        std::array<double, 2>& escaped) const
    {
        const int halves = rise > 0.0 ? 2 : 1;
        const int drift[2] = {halves == 1 ? 0 : 1, -1};   // per half
        std::array<std::vector<double>, 2> wrapping;
        std::array<double, 2> transit{0.0, 0.0};
        for (int h = 0; h < halves; ++h) {
            wrapping[size_t(h)].assign(sliceSize(), 0.0);
            transit[size_t(h)] = wrap(d, exits, 1.0 / halves, drift[h], rise, upward,
                wrapping[size_t(h)], escaped);
        }
        const double first = transit[0] + transit[1];
        for (int h = 0; h < halves; ++h) {
            for (int w = 0; w < kMaxWraps && transit[size_t(h)] > 1e-9 * first; ++w) {
                entry.swap(wrapping[size_t(h)]);
                pass();
                std::fill(wrapping[size_t(h)].begin(), wrapping[size_t(h)].end(), 0.0);
                transit[size_t(h)] = wrap(d, exits, 1.0, drift[h], rise, upward,
                    wrapping[size_t(h)], escaped);
            }
        }
        for (size_t e = 0; e < sliceSize(); ++e) {
            carried[e] = wrapping[0][e] + (halves == 2 ? wrapping[1][e] : 0.0);
        }
    }

    /// Bytes per entry of the slices (the counts; the solver's carried light is its own).
    static constexpr size_t kBytesPerSlot = 4;

private:
    int layerOf(double height) const;
    int sideSlot(const openvdb::Vec3d& p, const openvdb::Vec3d& t, bool forward) const;
    int stepSlot(const openvdb::Coord& a, const openvdb::Coord& b, bool forward) const;
    size_t oppositeSlot(size_t e) const;

    openvdb::Vec3d mLo, mHi;
    openvdb::Coord mMin, mMax;
    int mUp = 1, mLayers = 0, mLayer0 = 0;
    FlatAxes mFlat{};
    std::vector<uint32_t> mEnterCount;
};

} // namespace vdbrad
