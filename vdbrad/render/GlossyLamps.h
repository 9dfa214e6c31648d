// GlossyLamps: what a solved glossy voxel sends along one direction, for a renderer's rays.
//
// A solved file keeps each glossy voxel's lobe only as its exitance (`specular_radiosity`, part
// of `radiosity`): the distribution on the control points stays in the solver. A gather ray that
// meets a glossy voxel would then see the lobe's light spread evenly over the hemisphere, and a
// highlight seen in another glossy surface (the lamp on a polished block, seen in its
// neighbour) comes out as a uniform glow: +21 % on the Cornell box's tall block against Cycles
// (docs/journal/2026-12-05-glossy-cornell-vs-cycles.md). Most of a highlight is the lamps'
// light, which a renderer knows exactly: per glossy voxel, the lamps' arrivals at its centre
// (DirectLightSampler, shadow rays) and their share of its reflected radiosity, ks sum E (the
// lobes reflect exactly ks: Brdf.h). sent() takes that share out of the even value and puts it
// back through the lobe,
//
//     sent(w) = reflected - ks sum_l E_l + ks sum_l E_l pi lobe(l, w),
//
// whose cosine-weighted mean over the hemisphere is `reflected` again; the rest of the lobe's
// light (from other surfaces) stays even.
#pragma once

#include "vdbrad/glossy/Brdf.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/surface/DirectLight.h"

#include <openvdb/math/Vec3.h>

#include <cstdint>
#include <map>
#include <utility>
#include <vector>

namespace vdbrad {

class GlossyLamps
{
public:
    /// @brief The lobes of @a scene's glossy voxels (@a model; one per rounded roughness, as
    /// the solver's: GlossySurfaces.h) and the lamps' arrivals at each of them, from
    /// @a sampler's shadow rays (in parallel; the scene and sampler must outlive this).
    GlossyLamps(const Scene& scene, const DirectLightSampler& sampler, BrdfModel model);

    /// The lobe of a glossy voxel of @a roughness.
    const Brdf& lobe(float roughness) const;

    /// @brief Reflected radiosity (B units: pi radiance) that voxel @a v sends along the
    /// index-space unit @a out, @a reflected being its direction-free value (B - E). A diffuse
    /// voxel's is @a reflected.
    openvdb::Vec3d sent(size_t v, const openvdb::Vec3d& out, const openvdb::Vec3d& reflected) const;

    /// The lamps' share of voxel @a v's reflected radiosity, ks sum E (0 for a diffuse voxel).
    const openvdb::Vec3d& lampShare(size_t v) const { return mLampShare[v]; }

private:
    const Scene& mScene;
    std::map<long, Brdf> mLobes;
    // Per voxel, its arrivals (local-frame unit direction, irradiance) from mStart[v] to
    // mStart[v + 1].
    std::vector<uint32_t> mStart;
    std::vector<std::pair<openvdb::Vec3d, openvdb::Vec3d>> mLamps;
    std::vector<openvdb::Vec3d> mLampShare;
};

} // namespace vdbrad
