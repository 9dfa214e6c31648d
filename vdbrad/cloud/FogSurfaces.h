// FogSurfaces: the surface voxels of a scene inside a participating medium (thesis §6.3.1: a
// fog in a room lit by its lamps), swept with the medium by CloudTransfer.
//
// The scene's voxels (Scene.h: normal, albedo, emission) are added to the swept voxels; where a
// surface voxel and a medium voxel coincide the surface wins (its fog is dropped). Each surface
// voxel lies on exactly one digital line of every direction, as the medium's voxels do, so the
// sweeps carry light onto it and off it with no geometry of their own. Surfaces are one-sided
// and opaque. Along a line in sense t, a surface voxel v of normal n with c = t.n:
//
//  - c > 0 (its front faces along the line): consecutive such voxels (neighbours on the line)
//    form a run that light leaves from; light coming into the run from behind is absorbed by
//    its back, and the line leaves the run's last voxel v with radiance B_v / Z_v,
//    Z_v = sum over the direction pairs of Omega |t.n_v| (~pi: the direction set's quadrature
//    of the cosine, so that a uniform radiosity B gives back the irradiance B exactly);
//  - c < 0 (its front faces against the line): the first of consecutive such voxels takes all
//    the line's power and the line goes on dark;
//  - c = 0: the line runs along the surface; the voxel is passed over.
//
// The side the fog is on overrides the normal: a voxel met right after a medium voxel (its
// neighbour on the line) takes the line's light even where c > 0, and a receiver right before a
// medium voxel sends into it. A normal only approximates the side at a digital edge, a corner
// or a staircase of a curved wall, where lines from the fog meet voxels whose normal faces
// along them; by their normals alone, their backs would absorb 4 % of the power in the Cornell
// box. (So a voxel with fog on both sides takes light from both.)
//
// The first receiver of a run along t is the last voxel of the run along -t, so the set of
// (direction, sense) through which a voxel receives mirrors the set it sends through: its area
// as the lines see it is
//
//     A_v = sum over the senses t in which v receives first of (Omega_t / step_t) / Z_v
//
// (Omega / step: the etendue of a line's tube), found by one geometric sweep. A voxel then sends
// out exactly P_v = B_v A_v, B_v = E_v + rho_v (power landed) / A_v: its emission E_v A_v and
// rho_v times what landed on it (lagged one sweep, as the medium's scattering is), so energy is
// exactly conserved, and under a uniform radiance L every voxel receives L Z_v A_v, an
// irradiance L Z_v: a closed room of uniform albedo and emission is exact voxel by voxel, with
// a conservative fog in it or not. The area comes from what the lines meet, so a voxel that
// only closes a digital edge or corner of a wall (it touches the air along an edge) has little
// area and emits little, as the surface there is small.
#pragma once

#include "vdbrad/scene/Cloud.h"
#include "vdbrad/scene/Scene.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <limits>
#include <vector>

namespace vdbrad {

class FogSurfaces
{
public:
    /// Marks a voxel of merged()'s result that is no surface voxel.
    static constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

    /// @brief The surface voxels of @a scene, channel @a channel (0, 1, 2) of an RGB scene's
    /// albedo and emission.
    /// @throw openvdb::ValueError if @a channel is not 0 for a grey scene or not 0-2 for RGB
    FogSurfaces(const Scene& scene, int channel);

    size_t size() const { return mNormal.size(); }
    const Scene& scene() const { return mScene; }
    int channel() const { return mChannel; }
    /// Per surface voxel (the scene's numbering): unit index-space normal, albedo, emission.
    const openvdb::Vec3f& normal(size_t s) const { return mNormal[s]; }
    float albedo(size_t s) const { return mAlbedo[s]; }
    float emission(size_t s) const { return mEmission[s]; }

    /// @brief @a cloud with the surface voxels added (extinction 0 there).
    /// @param fromCloud  for each voxel of the result, the voxel of @a cloud it is, or kNone
    /// @param surfaceOf  for each voxel of the result, the surface voxel it is, or kNone
    /// @throw openvdb::ValueError if the scene's transform is not the cloud's, or the result has
    ///        too many voxels
    Cloud merged(const Cloud& cloud, std::vector<uint32_t>& fromCloud,
        std::vector<uint32_t>& surfaceOf) const;

    /// @brief Per surface voxel, Z_v = sum over the direction pairs of omega_d |t_d . n_v|
    /// (see the file comment), from each pair's unit direction and solid angle as swept.
    std::vector<double> normalisers(const std::vector<openvdb::Vec3d>& units,
        const std::vector<float>& omega) const;

    /// Hash of what the sweeps read (normals, albedo, emission).
    uint64_t hash(uint64_t seed) const;

private:
    const Scene& mScene;
    int mChannel = 0;
    std::vector<openvdb::Vec3f> mNormal;
    std::vector<float> mAlbedo, mEmission;
};

} // namespace vdbrad
