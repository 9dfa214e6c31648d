// ScatteredSource: what a solved cloud hands to a renderer so that the picture shows the light
// the solve found in the direction the camera looks, not its mean over directions.
//
// The cloud solver (CloudTransfer.h) solves a delta-M scaled problem: extinction
// sigma' = (1 - omega0 f) sigma, the phase function truncated at order K, the sun's beam
// attenuated by sigma' and its first scattering taken with the full phase function. Radiance
// towards the eye then integrates, along the camera ray with sigma', the source
//
//     S(s) = sum_lm c_lm Y_lm(s)                                 multiple scattering (solved)
//          + omega0 / (1 - omega0 f) p(-sun . s) F0 T'_sun / 4pi   the sun's single scattering
//          + epsilon / sigma'                                      the medium's emission
//
// (s the direction of travel towards the eye, index space; p the full phase function,
// (1/4pi) int p = 1; T'_sun the beam's transmittance to the point, through sigma'): Nakajima
// and Tanaka's TMS correction (1988), where the first scattering of the sun, which carries the
// forward peak delta-M cut off (a cloud's silver lining), is exact and only the diffuse field
// comes from the truncated solve. The file carries the c_lm as grids, one per coefficient,
// named `<J>_sh<k>` (J the mean-intensity grid's name, k = l^2 + l + m), float or vec3s like
// J, and on J the metadata below.
#pragma once

#include "vdbrad/cloud/PhaseFunction.h"

#include <openvdb/openvdb.h>

#include <optional>
#include <string>
#include <vector>

namespace vdbrad {

struct ScatteredSource
{
    /// The most a solve writes ((K + 1)^2 grids), and by default: all the solve has (the
    /// WDAS cloud at g 0.877 drawn from order 4 is 1.4-3.8 % off its picture from order 8:
    /// docs/journal/2026-12-08-cloud-pictures.md).
    static constexpr int kMaxOrder = 16;
    static constexpr int kDefaultOrder = kMaxOrder;

    /// Harmonic order K of the moments written: (K + 1)^2 grids.
    int order = 0;
    /// The full phase function and the delta-M fraction f the solve moved forward.
    PhaseFunction phase;
    double deltaM = 0.0;
    /// Unit index-space direction towards the sun, and the beam's irradiance F0 on a plane
    /// normal to it (RGB; zero: no sun).
    openvdb::Vec3d toSun{0.0, 1.0, 0.0};
    openvdb::Vec3d sunIrradiance{0.0};
    /// Periodic across the horizontal axes (shadow rays wrap around), and which axis is up.
    bool periodic = false;
    int up = 1;
    /// The (K + 1)^2 coefficient grids, in k order.
    std::vector<openvdb::GridBase::ConstPtr> moments;

    /// @brief The name of coefficient @a k's grid for mean-intensity grid @a J.
    static std::string gridName(const std::string& J, int k)
    {
        return J + "_sh" + std::to_string(k);
    }

    /// @brief Write everything but the moments as metadata on @a J.
    void record(openvdb::GridBase& J) const;
    /// @brief Read it back from @a J and @a grids (the file's); none where @a J carries no
    /// `vdbrad:scattering` metadata (a file solved before it, or J made by hand).
    /// @throw openvdb::ValueError for metadata that is there but broken, a coefficient grid
    ///        missing, of another type than J, or on another transform
    static std::optional<ScatteredSource> read(const openvdb::GridBase& J,
        const openvdb::GridPtrVec& grids);
};

} // namespace vdbrad
