// FinalGather: the light at a point a camera sees on a solved surface, gathered by rays.
//
// A solved file has one value per surface voxel: ray effects of the sweeps and the stairs of
// tilted walls show in a picture of it. The final gather (RenderOptions::gather) recomputes the
// radiosity at the visible point from the solution one bounce away, E + rho (D + G): D the exact
// direct light there (DirectLight.h), G the mean reflected radiosity B - E of what cosine rays
// from the point hit (SurfaceRays.h). Glossy voxels (RenderOptions::glossyRays) reflect
// towards the camera what rays drawn from their lobe hit, plus the lamps through the lobe
// (GlossyLamps.h): highlights.
#pragma once

#include "vdbrad/core/Attribute.h"
#include "vdbrad/render/GlossyLamps.h"
#include "vdbrad/render/Renderer.h"
#include "vdbrad/surface/DirectLight.h"
#include "vdbrad/sweep/Enclosure.h"

#include <memory>
#include <optional>
#include <vector>

namespace vdbrad {

class FinalGather
{
public:
    /// @brief Gather over @a scene solved to @a radiosity (total, per scene voxel), as
    /// @a options says (gather and glossy rays, shadow rays, the sky and sun it was solved
    /// under). The scene and options must outlive this.
    FinalGather(const Scene& scene, const Attribute& radiosity, const RenderOptions& options);

    /// Glossy voxels reflect through their lobes (@a model, as solved) from now on.
    void addLobes(BrdfModel model);
    bool glossy() const { return bool(mLobes); }

    /// Per-thread state: the surface's accessor and the shadow rays' workspaces.
    struct Workspace
    {
        explicit Workspace(const FinalGather& g);
        VoxelIndex::Accessor surface;
        DirectLightSampler::Workspace direct, lobeDirect;
    };

    /// @brief E + rho (D + G) at index-space point p seen on voxel v (moved onto v's plane,
    /// SurfacePlanes.h, inside its cube), the rays about @a smooth (a mesh's or level set's
    /// normal there) or v's normal, the sample sequences hashed from @a h. @a solved (v's
    /// solved value) when every ray goes through a digitisation crack.
    openvdb::Vec3f gather(const openvdb::Vec3d& p, size_t v, uint64_t h,
        const openvdb::Vec3f* smooth, const openvdb::Vec3f& solved, Workspace& ws) const;

    /// @brief What glossy voxel v's lobe reflects towards the eye (index-space unit @a toEye)
    /// at the index-space point p: ks (lamps through the lobe + the lobe's gather), the
    /// sample sequences hashed from @a h. Zero for a diffuse voxel or one seen from behind.
    openvdb::Vec3f glossy(const openvdb::Vec3d& p, size_t v, const openvdb::Vec3d& toEye,
        uint64_t h, Workspace& ws) const;

private:
    // p moved onto voxel v's plane, kept inside its cube.
    openvdb::Vec3d onPlane(const openvdb::Vec3d& p, size_t v) const;

    const Scene& mScene;
    const RenderOptions& mOptions;
    Emitters mEmitters;
    Regions mRegions;
    DirectLightSampler mSampler;
    openvdb::CoordBBox mBox;
    std::vector<openvdb::Vec3d> mReflected;   // B - E per voxel
    std::unique_ptr<GlossyLamps> mLobes;
};

} // namespace vdbrad
