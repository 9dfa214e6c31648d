// Ground: a Lambertian surface under a cloud (CloudTransfer with CloudTransferOptions::ground).
//
// The ground is a layer of voxels one below the cloud's box, over the box's footprint, added to
// the swept voxels: each of its cells lies on exactly one digital line of every direction, as
// the medium's voxels do, so the sweeps carry light onto it and off it with no geometry of their
// own. A line going down meets the ground layer and leaves all its power on the first ground
// cell it crosses (the layer is opaque); a line going up starts in it and gathers, from each
// ground cell it runs through, that cell's share of what it reflects into the line's direction:
//
//     power into direction d from cell c = rho E_c w_d,   w_d = Omega_d mu_d / sum_d' Omega_d' mu_d',
//
// E_c the power that landed on the cell (its irradiance: a cell is one voxel face) and mu_d the
// direction's cosine with the vertical. The lines of a direction partition the layer, so what a
// cell reflects goes out in full, whatever the digital lines look like; along a shallow
// direction a line runs over several cells and carries their sum, which is the radiance
// rho E / pi of a Lambertian surface on the line's cross-section (its tube crosses the ground
// plane over those cells). The weights w_d are the direction set's quadrature of the cosine
// law, normalised so that the ground reflects exactly rho E: energy stays exactly balanced.
//
// The reflected light is lagged one iteration, like the scattering source: what lands in a sweep
// leaves the ground in the next, and Anderson acceleration mixes it with the medium's moments.
// Periodic boxes: the layer is part of the box, its lines wrap as the medium's do, so the ground
// is the infinite repeating one under the repeating cloud. Open boxes: the ground covers the
// box's footprint only; light that leaves through a side face is gone (pad the box with clear
// air to widen the ground).
#pragma once

#include "vdbrad/scene/Cloud.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <limits>
#include <vector>

namespace vdbrad {

class GroundLayer
{
public:
    /// Marks a voxel of withGround()'s result that is a ground cell.
    static constexpr uint32_t kGround = std::numeric_limits<uint32_t>::max();

    GroundLayer() = default;
    /// @brief The layer under @a box (index space), @a up the vertical axis.
    GroundLayer(const openvdb::CoordBBox& box, int up);

    /// Index coordinate of the layer along the vertical axis.
    int layer() const { return mLayer; }
    int up() const { return mUp; }
    /// Cells: the footprint of the box, first horizontal axis (up + 1) % 3 slowest.
    size_t size() const { return size_t(mDim[0]) * size_t(mDim[1]); }
    bool contains(const openvdb::Coord& ijk) const { return ijk[mUp] == mLayer; }
    /// Cell of a voxel of the layer.
    size_t cell(const openvdb::Coord& ijk) const
    {
        return size_t(ijk[mAxis[0]] - mMin[mAxis[0]]) * size_t(mDim[1])
            + size_t(ijk[mAxis[1]] - mMin[mAxis[1]]);
    }
    openvdb::Coord coord(size_t cell) const;
    /// The layer's voxels, index space.
    openvdb::CoordBBox bbox() const;
    /// @brief The cell where the line through index-space point @a p along @a t (going down)
    /// meets the plane of the layer's top face (the box's bottom): wrapped into the footprint
    /// if @a periodic, else -1 outside it.
    int64_t cellBelow(const openvdb::Vec3d& p, const openvdb::Vec3d& t, bool periodic) const;

    /// @brief @a cloud with the layer's cells added as voxels (extinction 0).
    /// @param source  if not null, for each voxel of the result the voxel of @a cloud it is, or
    ///                kGround for a ground cell
    /// @throw openvdb::ValueError if the result has too many voxels (VoxelIndex)
    Cloud withGround(const Cloud& cloud, std::vector<uint32_t>* source = nullptr) const;

private:
    int mUp = 1, mLayer = 0;
    int mAxis[2] = {2, 0};
    openvdb::Coord mMin{0, 0, 0};
    int mDim[2] = {0, 0};
};

/// @brief Per direction pair: the radiance a line along the pair's upward sense gains from a
/// ground cell that reflects power P, divided by P: w_d / etendue_d, w_d = Omega_d mu_d / sum
/// over pairs of Omega mu (see the file comment), etendue_d = Omega_d / step_d.
/// @param omega  per pair, the solid angle of one sense as the sweeps weight it
/// @param mu     per pair, |cosine| of the direction with the vertical (0: horizontal)
/// @param step   per pair, the swept line's step in voxels
std::vector<double> groundEmission(const std::vector<float>& omega, const std::vector<double>& mu,
    const std::vector<float>& step);

} // namespace vdbrad
