// DirectLight: the exact first-collision irradiance of every surface voxel from the emitters.
//
// A fixed direction set sees a small light through a few directions only, and which ones
// changes from voxel to voxel: stripes ("ray effects"), 24 % mean error on a floor under a small
// quad at 1000 directions. Direct light is instead integrated here over the emitters' surfaces
// (Emitters.h) and the sweeps carry only what is reflected (RadiositySolver.h):
//
//   D(x) = sum over patches g of  M_g  F(x, g)  V(x, g)
//
// F(x, g): the exact form factor of patch g from the centre p of x with normal n, by Lambert's
// contour formula over g's outline, (1 / 2 pi) sum over edges (a, b) of
// angle(a - p, b - p) n . unit((a - p) x (b - p)), after clipping the outline to x's hemisphere
// (Sutherland-Hodgman; x behind g's plane, or g entirely behind x: 0). A patch more than 32
// radii away is a point source (relative error below ~1e-3). No noise, whatever the distance.
//
// V(x, g): the share of g that x sees, weighted by the integrand cos cos / r^2, from S shadow
// rays per voxel (DirectLightOptions::samples), dealt to the patches in proportion to M_g F(x, g)
// by stratified sampling and to points of a patch uniformly by area. A ray follows the same
// rule as the Monte Carlo reference (VoxelMarch.h, crossesVoxelSurface): it is stopped by the
// first voxel whose plane it crosses inside the voxel's cube, and arrives when it reaches a
// voxel of g or g's plane. A ratio estimator: where g is wholly seen or wholly hidden, D is
// exact; only penumbrae carry sampling error. Each voxel's sample points come from a counter-
// based hash of (seed, voxel), so D is bit-identical for any thread count.
//
// The sun (DirectLightOptions::sun, Sun.h) adds E max(0, n . s) V(x, sun): V from S shadow rays
// towards points of its disk (its penumbra), each stopped by the same rule, the cosine taken at
// the disk's centre (over a 0.53 degree disk it varies by ~1e-5).
//
// Cost: per voxel, one form factor per patch in front of it (about 20 ns per outline edge) and
// S rays through the index tree (docs/journal/2026-12-03-exact-direct-light.md).
#pragma once

#include "vdbrad/scene/Emitters.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/scene/Sun.h"
#include "vdbrad/scene/SurfacePlanes.h"

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <cstdint>
#include <functional>
#include <optional>
#include <tuple>
#include <utility>
#include <vector>

namespace vdbrad {

/// How the light emitters send before any reflection reaches a voxel.
enum class DirectMode
{
    /// Through the direction set, like every other bounce (the method as published).
    Sweep,
    /// Integrated exactly over the emitters (this file); the sweeps carry reflected light only.
    Exact,
    /// Exact when something emits and the emitting voxels are at most half of the surface, or
    /// when there is a sun.
    /// Where emitters cover most of the scene every receiver sees them through many directions
    /// (no stripes), and a closed furnace, all emitters, stays exact to rounding through the
    /// sweeps' per-voxel normalisation (an exact integral over voxel patches would not close).
    Auto
};

class Distribution;

struct DirectLightOptions
{
    /// Shadow rays per voxel, >= 1.
    int samples = 16;
    /// Seed of the per-voxel sample sequences.
    uint64_t seed = 1;
    /// The MPI job whose ranks share the voxels out (Distribution.h); null: this process.
    const Distribution* ranks = nullptr;
    /// A sun beside the emitters (none: the emitters alone).
    std::optional<Sun> sun;
};

/// True if @a mode resolves to exact direct light for @a scene (something emits, or @a sun;
/// Auto: at most half of its voxels emit, or a sun).
bool usesExactDirect(DirectMode mode, const Scene& scene, bool sun = false);

/// @brief The form factor from a point @a p with unit normal @a n to a planar polygon given by
/// its closed loops (holes running the other way), clipped to the hemisphere of @a n.
/// Non-negative; exact up to rounding.
double polygonFormFactor(const openvdb::Vec3d& p, const openvdb::Vec3d& n,
    const std::vector<std::vector<openvdb::Vec3d>>& loops);

/// @brief Unoccluded form factor from @a p (normal @a n) to @a patch: 0 behind its plane, the
/// point-source value far away, polygonFormFactor() otherwise.
double patchFormFactor(const openvdb::Vec3d& p, const openvdb::Vec3d& n,
    const EmitterPatch& patch);

/// @brief The direct light at any surface point: what directIrradiance() computes at voxel
/// centres, for a renderer's gather at a pixel's visible point. Read-only: at() may be called
/// from several threads, each with its own Workspace.
class DirectLightSampler
{
public:
    /// @param regions  as directIrradiance()'s; kept by pointer (must outlive the sampler)
    /// @throw openvdb::ValueError if options.samples < 1
    DirectLightSampler(const Scene& scene, const Emitters& emitters,
        const DirectLightOptions& options, const std::vector<uint32_t>* regions = nullptr);

    /// Per-thread scratch memory, and the rays and form factors it has counted.
    struct Workspace
    {
        explicit Workspace(const DirectLightSampler& sampler);
        VoxelIndex::Accessor acc;
        std::vector<double> weight, factor, shares;
        std::vector<uint32_t> front;
        uint64_t rays = 0, factors = 0;
        /// If not null, at() also says where the light comes from (glossy receivers): pairs of
        /// a unit direction towards an emitter and the irradiance arriving from it, adding up
        /// to what at() returns. Each patch's light is dealt to its samples that arrived, by
        /// their weights (to its centre if none did).
        std::vector<std::pair<openvdb::Vec3d, openvdb::Vec3d>>* incident = nullptr;
        std::vector<std::tuple<uint32_t, openvdb::Vec3d, double>> arrivals;   // (front, dir, w)
    };

    /// The voxels' planes and the surface rule the shadow rays follow.
    const SurfacePlanes& planes() const { return mPlanes; }

    /// @brief Direct irradiance (per channel) at index-space point @a p with unit normal @a n
    /// on voxel @a self (its own patch and its own cube do not count), from the sample
    /// sequence of hash @a h.
    openvdb::Vec3d at(const openvdb::Vec3d& p, const openvdb::Vec3d& n, size_t self, uint64_t h,
        Workspace& workspace) const;

private:
    openvdb::Vec3d emittersAt(const openvdb::Vec3d& p, const openvdb::Vec3d& n, size_t self,
        uint64_t h, Workspace& workspace) const;
    openvdb::Vec3d sunAt(const openvdb::Vec3d& p, const openvdb::Vec3d& n, size_t self,
        uint64_t h, Workspace& workspace) const;

    const Scene& mScene;
    const Emitters& mEmitters;
    DirectLightOptions mOptions;
    const std::vector<uint32_t>* mRegions;
    openvdb::CoordBBox mBox;
    std::vector<uint32_t> mPatchRegion;   // the room each patch faces
    SurfacePlanes mPlanes;                // each voxel's plane, the surface rule
    // The sun: towards it (unit, index space), two unit axes across it, its angular radius
    // (radians) and the length of a ray that leaves the box.
    openvdb::Vec3d mToSun{0.0}, mAcross1{0.0}, mAcross2{0.0};
    double mSunRadius = 0.0, mRayLength = 0.0;
};

struct DirectIrradiance
{
    /// Per voxel (Scene order), per channel (grey scenes: three equal channels).
    std::vector<openvdb::Vec3f> irradiance;
    uint64_t rays = 0;        // shadow rays cast
    uint64_t factors = 0;     // exact (contour) form factors evaluated
    double seconds = 0.0;
};

/// Where a voxel's direct light comes from (DirectLightSampler::Workspace::incident's pairs),
/// for the voxels that ask: wants(i) selects them, take(i, pairs) receives each one's (called
/// from several threads, once per selected voxel).
struct IncidentSink
{
    std::function<bool(size_t)> wants;
    std::function<void(size_t, const std::vector<std::pair<openvdb::Vec3d, openvdb::Vec3d>>&)>
        take;
};

/// @brief D(x) for every voxel of @a scene from @a emitters (see the file comment).
/// @param regions  optional, per voxel, the closed cavity it faces (Enclosure.h, 0: outside): a
///        voxel facing a closed room takes light only from patches facing the same room, as the
///        sweeps and the Monte Carlo reference count only what a room's walls see (a tilted
///        edge voxel's hemisphere pokes out through its own cube: a digitisation artefact)
/// @throw openvdb::ValueError if options.samples < 1; vdbrad::Cancelled if @a interrupt asks
///        to stop
/// @param incident  optional: also where the selected voxels' light comes from (glossy voxels)
DirectIrradiance directIrradiance(const Scene& scene, const Emitters& emitters,
    const DirectLightOptions& options = DirectLightOptions(),
    const std::vector<uint32_t>* regions = nullptr,
    openvdb::util::NullInterrupter* interrupt = nullptr, const IncidentSink* incident = nullptr);

} // namespace vdbrad
