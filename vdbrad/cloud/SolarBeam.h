// SolarBeam: the direct (unscattered) sunlight in a cloud, attenuated exactly along its own
// direction, and the power it loses in each medium voxel: the first-order source of the diffuse
// field, as radiative-transfer codes split it off (thesis §6.3 lacked exact path lengths and
// oblique sun).
//
// A bundle of parallel rays covers the box's shadow on the plane normal to the beam with a
// regular grid of `raysPerVoxel`^2 rays per voxel face area. Each ray carries F0 times its share
// of that area and marches through the voxel cubes (index space) with exact chord lengths l:
// crossing a voxel of optical depth per voxel length k, it keeps exp(-k l) and deposits the rest
// there. So the deposits and the transmitted power add up to the incident power exactly
// (telescoping products), whatever the sampling; the sampling only decides how finely the beam's
// shadow edges are resolved (exact for a horizontally uniform medium under any sun).
//
// Open boundaries: the bundle covers the projection of the whole medium box (top and sunlit
// sides). Periodic boundaries (the two horizontal axes): rays start on the box's top face, over
// one period, and wrap around horizontally until they leave through the bottom, so a finite box
// stands for an infinite repeating field. Over a ground (Ground.h), what is left of each ray
// lands on the ground cell where it meets the ground's plane; an open box's rays then start on
// the plane of its top face (over the footprint and upstream of it), so that they meet the
// ground equally spaced.
#pragma once

#include "vdbrad/cloud/Ground.h"
#include "vdbrad/core/VoxelIndex.h"
#include "vdbrad/scene/Sun.h"

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <vector>

namespace vdbrad {

struct SolarBeamResult
{
    /// Per medium voxel (VoxelIndex numbering): beam power lost there (extinguished: absorbed
    /// plus scattered), in units of F0 times a voxel face area.
    std::vector<double> deposited;
    /// Beam power entering the box and leaving it unscattered, same units.
    double incident = 0.0, transmitted = 0.0;
    /// With a ground: per cell of its layer, the part of `transmitted` that reaches it.
    std::vector<double> ground;
};

/// @brief Trace the solar beam through a medium.
/// @param voxels       the medium voxels
/// @param opticalDepth per voxel, optical depth per voxel length (sigma_t times voxel size), >= 0
/// @param toSun        index-space direction towards the sun (need not be unit); its component
///                     along @a up must be > 0
/// @param up           0, 1 or 2: the vertical axis
/// @param periodic     wrap the two horizontal axes over the voxels' bounding box
/// @param raysPerVoxel rays per voxel along each axis of the beam's cross-section, >= 1
/// @param irradiance   F0, beam irradiance on a plane normal to it, >= 0
/// @param ground       if not null, a ground under the medium (Ground.h): where each ray meets
///                     its plane, wrapped into the period if periodic, or nowhere if outside its
///                     footprint; @a voxels may hold the ground's layer (CloudTransfer sweeps
///                     it), which is not part of the medium's box
/// @param opaque       if not null, per voxel: nonzero for a surface (FogSurfaces.h), where a
///                     ray that reaches it leaves all its power (in `deposited`) and ends
/// @throw openvdb::ValueError for invalid arguments; vdbrad::Cancelled if @a interrupt asks
SolarBeamResult traceSolarBeam(const VoxelIndex& voxels, const std::vector<float>& opticalDepth,
    const openvdb::Vec3d& toSun, int up, bool periodic, int raysPerVoxel = 2,
    double irradiance = 1.0, openvdb::util::NullInterrupter* interrupt = nullptr,
    const GroundLayer* ground = nullptr, const std::vector<uint8_t>* opaque = nullptr);

} // namespace vdbrad
