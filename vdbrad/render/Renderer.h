// Renderer: a picture of a solved scene, as seen by a pinhole camera.
//
// A radiosity solve gives one value per surface voxel; the renderer only has to show it. Per pixel
// sample, a primary ray from the camera finds
//   - the first surface hit: for explicit surfaces (`normal` grid) the first surface voxel cube
//     [ijk - 0.5, ijk + 0.5] (index space) the ray enters, found by a voxel DDA that jumps over
//     the empty nodes of the voxel index tree; for level-set scenes the level set's zero crossing
//     (tools::LevelSetRayIntersector), whose silhouettes are smooth rather than voxel steps;
//     given the mesh the scene was voxelised from (RenderOptions::mesh), the mesh's own
//     triangles (MeshTracer.h), whose outlines are exact;
//   - its radiosity, interpolated smoothly across neighbouring surface voxels, as the thesis'
//     Voxelizator did: at the hit point p the surface voxels among the 2x2x2 voxel centres around
//     p are blended with trilinear weights times max(0, n_i . n_hit) and renormalised. The normal
//     factor keeps the other side of a thin wall and a perpendicular wall at a corner from bleeding
//     in; if every weight vanishes the hit voxel's own value is used;
//   - a cloud's emission and absorption along the ray, when the file has a `density` fog volume
//     (docs/scene-contract.md): extinction sigma_t (per world unit), source S = omega0 J with J
//     the cloud solver's mean intensity. Voxels are piecewise constant, so the transfer equation
//     dL/ds = -sigma_t (L - S) integrates exactly per voxel chord of length l:
//         L += T (1 - exp(-sigma_t l)) S,   T *= exp(-sigma_t l),
//     with 1 - exp(-x) evaluated as -expm1(-x) so thin clouds keep their precision. A surface
//     behind or inside the cloud is seen attenuated by T, the background likewise;
//   - the ground under a cloud, when the file has the cloud solver's `ground_irradiance`
//     (CloudTransfer::groundGrid): seen from above on the top face of its layer, radiosity
//     rho E.
//
// Units: a pixel holds the radiosity B of what it sees (not the radiance B / pi), in the solve's
// units: an emitter of emission 1 shows as 1.0. Pixels are linear (no tone mapping; ImageIO.h).
#pragma once

#include "vdbrad/mesh/Mesh.h"
#include "vdbrad/scene/Cloud.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/scene/Sky.h"
#include "vdbrad/scene/Sun.h"

#include <openvdb/openvdb.h>
#include <openvdb/math/Ray.h>
#include <openvdb/util/NullInterrupter.h>

#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace vdbrad {

class CloudShading;
class FinalGather;

/// A pinhole camera in world space.
struct Camera
{
    openvdb::Vec3d eye{0.0}, target{0.0, 0.0, 1.0}, up{0.0, 1.0, 0.0};
    double fov = 40.0;   ///< vertical field of view, degrees, in (0, 180)
};

struct RenderOptions
{
    int width = 640, height = 480;   ///< pixels, each in [1, 16384]
    std::optional<Camera> camera;    ///< none: defaultCamera() of the scene's bounds
    openvdb::Vec3f background{0.f};  ///< what rays that hit nothing see (linear, finite)
    /// The light from outside the scene it was solved with (Sky.h), or none: rays that hit
    /// nothing see pi times its radiance (radiosity units) instead of the background, and the
    /// final gather's rays that leave the scene gather it.
    Sky sky;
    /// The sun it was solved with: the final gather's direct light includes it.
    std::optional<Sun> sun;
    /// n: n x n sub-pixel samples on a regular grid (stratum centres), averaged; in [1, 16].
    int samplesPerPixel = 1;
    SceneOptions scene;              ///< how to read the surface: the same as for the solve
    CloudOptions cloud;              ///< how to read the cloud: the same as for the solve
    /// Final gather (surfaces): rays per pixel sample from the visible point, 0 for none. The
    /// pixel then shows E + rho (D + G) at the point of the voxel's own plane the camera sees:
    /// D the exact direct light there (DirectLight.h), G the mean reflected radiosity B - E of
    /// what the gather's cosine-distributed rays hit (SurfaceRays.h). Smooth where the voxels'
    /// values are not (ray effects of the sweeps, stairs of tilted walls); it needs the scene's
    /// albedo and emission, which the solved file carries.
    int gather = 0;
    /// Shadow rays per pixel sample for the gather's direct light (>= 1).
    int directSamples = 16;
    /// Glossy surfaces (a solved file with `specular_radiosity`): rays per pixel sample that
    /// gather the light a glossy voxel's lobe reflects towards the camera, drawn from the lobe
    /// (Brdf::sample) and reading the radiosity of what they hit, plus the lamps' light
    /// through the lobe by directSamples shadow rays: highlights. The voxel's diffuse part is
    /// shown as for every voxel (its `radiosity` less `specular_radiosity`, or the gather's).
    /// 0: the lobe's exitance, the same from every direction.
    int glossyRays = 32;
    /// The mesh the surface was voxelised from (world units, as `vdbrad voxelize` read it), or
    /// none. Rays then find the mesh's triangles instead of the voxels, so outlines are exact
    /// rather than up to a voxel out; what a hit shows is still the voxels' radiosity around it
    /// (or the gather from it). The mesh must lie within the surface voxels' bounds.
    std::shared_ptr<const TriangleMesh> mesh;
    /// Name of the cloud's source grid J (float or Vec3f, mean radiance over directions, as the
    /// cloud solver writes it). Missing: the cloud only absorbs (see Image::warnings).
    std::string cloudSource = "mean_intensity";
    /// Clouds: voxels per step of the ray march through the trilinear fields (CloudShading.h),
    /// in (0, 4].
    double cloudStep = 0.5;
    /// Clouds: the highest order of the solved scattered light's moments used (at most what
    /// the file has; -1: all of them).
    int cloudSourceOrder = -1;
};

/// A linear RGB image.
struct Image
{
    int width = 0, height = 0;
    /// Row-major, top row first, linear values (RenderOptions' units).
    std::vector<openvdb::Vec3f> pixels;
    /// Per pixel, how much of it shows the scene rather than the background, in [0, 1]: the mean
    /// over its samples of 1 for a ray that hits a surface, 1 - (cloud transmittance) for one
    /// that does not. Auto-exposure (ImageIO.h) uses it to leave the background out.
    /// Empty when unknown (a decoded file): every pixel then counts.
    std::vector<float> coverage;
    /// Messages for the user about how the image was made (e.g. a cloud rendered without its
    /// source grid). The library never prints; the command-line tool shows them.
    std::vector<std::string> warnings;

    openvdb::Vec3f& at(int x, int y) { return pixels[size_t(y) * size_t(width) + size_t(x)]; }
    const openvdb::Vec3f& at(int x, int y) const
    {
        return pixels[size_t(y) * size_t(width) + size_t(x)];
    }
};

/// @brief A camera looking along +z from the -z side (the Cornell box is open towards -z), up +y,
/// at the centre of @a worldBounds, far enough that the whole box fits the vertical field of view
/// @a fov (degrees) and the horizontal one (aspect = width / height) with a 10% margin; the eye
/// lies in front of the box's near (-z) face.
/// @throw openvdb::ValueError if the box is empty or not finite, or @a aspect or @a fov is invalid
Camera defaultCamera(const openvdb::BBoxd& worldBounds, double aspect, double fov = 40.0);

/// @brief The engine behind renderImage(): reads the scene once, then traces rays.
///
/// Construction validates everything (grids, options, camera); render() and radiance() only read
/// and are safe to call from several threads.
class Renderer
{
public:
    using RayT = openvdb::math::Ray<double>;

    /// @brief Read the surface (with its `radiosity` grid) and the cloud of @a grids.
    /// @throw openvdb::ValueError bad options or camera, NaN values, no `radiosity` grid and no
    ///        cloud ("solve the scene first"), radiosity voxels that differ from the scene's
    ///        surface voxels (the --surface/--separation of the solve must be used again), or a
    ///        mesh outside the surface's bounds (not the mesh the scene was made from)
    /// @throw openvdb::TypeError  `radiosity` or the cloud source neither float nor vec3s
    /// @throw openvdb::KeyError   a `radiosity` grid but no surface to put it on
    /// @throw vdbrad::Cancelled   if @a interrupt asks to stop while the scene is read
    Renderer(const openvdb::GridPtrVec& grids, const RenderOptions& options,
        openvdb::util::NullInterrupter* interrupt = nullptr);
    ~Renderer();
    Renderer(const Renderer&) = delete;
    Renderer& operator=(const Renderer&) = delete;

    /// The camera in use (RenderOptions::camera or the default one).
    const Camera& camera() const { return mCamera; }
    const RenderOptions& options() const { return mOptions; }
    bool hasSurface() const { return mHasSurface; }
    bool hasCloud() const { return mHasCloud; }
    /// World-space bounds of everything visible (surface voxel cubes and cloud voxels).
    const openvdb::BBoxd& worldBounds() const { return mWorldBounds; }
    const std::vector<std::string>& warnings() const { return mWarnings; }

    /// @brief World-space primary ray through image position (@a x, @a y), in pixels from the
    /// top-left corner of the image (pixel (i, j) covers [i, i + 1) x [j, j + 1)).
    RayT primaryRay(double x, double y) const;

    /// @brief What the ray @a worldRay (its eye, unit direction and [t0, t1] range, world units)
    /// sees: the linear value a pixel would hold. @a coverage, if given, receives 1 - T as
    /// Image::coverage defines it. Convenient for single rays; render() is faster per ray.
    openvdb::Vec3f radiance(const RayT& worldRay, float* coverage = nullptr) const;

    /// @brief Render the whole image, rows in parallel.
    /// @throw vdbrad::Cancelled if @a interrupt asks to stop (checked once per row)
    Image render(openvdb::util::NullInterrupter* interrupt = nullptr) const;

private:
    // The constructor's steps: the solved surface (its scene, its @a radiosity checked against
    // the scene's voxels, the glossy lobes, the level set, the mesh), then the cloud (its
    // source, its ground).
    void setSurface(const openvdb::GridPtrVec& grids, const GridRoles& roles,
        const openvdb::GridBase::ConstPtr& radiosity, openvdb::util::NullInterrupter* interrupt);
    void setCloud(const openvdb::GridPtrVec& grids, openvdb::util::NullInterrupter* interrupt);
    void setMesh(const TriangleMesh& mesh);

    struct Tracer;          // per-thread state: accessors, the level-set intersector
    struct LevelSetShared;  // the intersector every Tracer copies (keeps its header out of ours)
    struct MeshShared;      // RenderOptions::mesh binned for tracing

    RenderOptions mOptions;
    Camera mCamera;
    // Camera frame: forward, right and up unit vectors, tan(fov / 2), aspect.
    openvdb::Vec3d mForward, mRight, mUp;
    double mTanHalf = 0.0, mAspect = 1.0;

    bool mHasSurface = false, mHasCloud = false;
    Scene mScene;
    // Final gather and glossy lobes (RenderOptions::gather, glossyRays; FinalGather.h).
    std::unique_ptr<FinalGather> mGather;
    Attribute mRadiosity;                    // per surface voxel, scene numbering (glossy
                                             // scenes with glossyRays: the diffuse part)
    openvdb::FloatGrid::Ptr mLevelSet;       // level-set scenes only (a shallow copy)
    std::unique_ptr<LevelSetShared> mLevelSetShared;
    std::unique_ptr<MeshShared> mMesh;
    Cloud mCloud;
    std::unique_ptr<CloudShading> mShading;  // the cloud's fields and source towards the eye
    // The ground under the cloud, if the file has one (its irradiance E; drawn as rho E).
    openvdb::FloatGrid::ConstPtr mGround;
    float mGroundAlbedo = 0.f;
    int mGroundUp = 1, mGroundLayer = 0;
    openvdb::CoordBBox mSurfaceBox, mCloudBox;   // index bounds of the voxel sets
    openvdb::BBoxd mWorldBounds;
    std::vector<std::string> mWarnings;
};

/// @brief Render @a grids (a solved file) as RenderOptions says: Renderer(grids, options).render().
/// @throw as Renderer's constructor and Renderer::render
///
/// @code
/// vdbrad::VdbFile file = vdbrad::readVdbFile("cornell_lit.vdb");
/// vdbrad::RenderOptions options;
/// options.samplesPerPixel = 2;
/// vdbrad::Image image = vdbrad::renderImage(file.grids, options);
/// vdbrad::writeFileAtomic("cornell.exr", vdbrad::encodeExr(image));
/// @endcode
Image renderImage(const openvdb::GridPtrVec& grids, const RenderOptions& options = RenderOptions(),
    openvdb::util::NullInterrupter* interrupt = nullptr);

} // namespace vdbrad
