#include "vdbrad/render/Renderer.h"

#include "vdbrad/render/CloudShading.h"

#include "vdbrad/core/Constants.h"
#include "vdbrad/core/SampleHash.h"
#include "vdbrad/glossy/Brdf.h"
#include "vdbrad/glossy/ControlPoints.h"
#include "vdbrad/glossy/GlossySurfaces.h"
#include "vdbrad/mesh/MeshTracer.h"
#include "vdbrad/render/FinalGather.h"
#include "vdbrad/scene/Emitters.h"
#include "vdbrad/surface/DirectLight.h"
#include "vdbrad/surface/SurfaceRays.h"
#include "vdbrad/sweep/Enclosure.h"

#include "vdbrad/core/Errors.h"
#include "vdbrad/core/GridContract.h"
#include "vdbrad/core/VoxelMarch.h"
#include "vdbrad/scene/OutputGrids.h"

#include <openvdb/math/Stencils.h>
#include <openvdb/tools/RayIntersector.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <sstream>

namespace vdbrad {

using openvdb::Coord;
using openvdb::CoordBBox;
using openvdb::Vec3d;
using openvdb::Vec3f;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
// A ray whose transmittance falls below this sees nothing more (its remaining contribution is
// below float precision for any sensible background).
constexpr double kOpaque = 1e-10;

using Accessor = VoxelIndex::Accessor;
using LevelSetIntersector = openvdb::tools::LevelSetRayIntersector<openvdb::FloatGrid>;

template<typename VecT>
bool finite(const VecT& v)
{
    return std::isfinite(v[0]) && std::isfinite(v[1]) && std::isfinite(v[2]);
}

// Index-space ray of a world-space ray, parametrised by world distance: the same t in both.
struct IndexRay
{
    Vec3d origin, dir;
};

IndexRay
toIndex(const openvdb::math::Transform& xform, const Vec3d& eye, const Vec3d& dir)
{
    return IndexRay{xform.worldToIndex(eye), xform.baseMap()->applyInverseJacobian(dir)};
}

// World bounds of the cubes of the voxels in @a b.
openvdb::BBoxd
worldBoundsOf(const CoordBBox& b, const openvdb::math::Transform& xform)
{
    const openvdb::BBoxd cubes(b.min().asVec3d() - Vec3d(0.5), b.max().asVec3d() + Vec3d(0.5));
    return xform.indexToWorld(cubes);
}

void
checkCamera(const Camera& cam)
{
    if (!finite(cam.eye) || !finite(cam.target) || !finite(cam.up) || !std::isfinite(cam.fov)) {
        OPENVDB_THROW(openvdb::ValueError, "camera has a NaN or infinite value (eye " << cam.eye
            << ", target " << cam.target << ", up " << cam.up << ", fov " << cam.fov << ")");
    }
    if (!(cam.fov > 0.0 && cam.fov < 180.0)) {
        OPENVDB_THROW(openvdb::ValueError, "camera field of view must be in (0, 180) degrees, got "
            << cam.fov);
    }
    const Vec3d view = cam.target - cam.eye;
    if (!(view.length() > 0.0)) {
        OPENVDB_THROW(openvdb::ValueError, "camera eye and target are the same point " << cam.eye);
    }
    // A relative test: the up vector must not be (nearly) parallel to the view direction.
    if (!(view.unit().cross(cam.up).length() > 1e-6 * cam.up.length())
        || !(cam.up.length() > 0.0)) {
        OPENVDB_THROW(openvdb::ValueError, "camera up vector " << cam.up
            << " is zero or parallel to the view direction " << view.unit());
    }
}

template<typename GridT>
size_t
missingVoxels(const GridT& grid, const VoxelIndex& index)
{
    return tbb::parallel_reduce(tbb::blocked_range<size_t>(0, index.leafCount()), size_t(0),
        [&](const tbb::blocked_range<size_t>& r, size_t missing) {
            auto acc = grid.getConstAccessor();
            for (size_t n = r.begin(); n != r.end(); ++n) {
                for (size_t i = index.leafBegin(n); i < index.leafBegin(n + 1); ++i) {
                    if (!acc.isValueOn(index.coord(i))) ++missing;
                }
            }
            return missing;
        }, [](size_t a, size_t b) { return a + b; });
}

} // namespace

// ---- camera ------------------------------------------------------------------------------------

Camera
defaultCamera(const openvdb::BBoxd& worldBounds, double aspect, double fov)
{
    const Vec3d lo = worldBounds.min(), hi = worldBounds.max();
    if (!finite(lo) || !finite(hi) || !(hi[0] >= lo[0] && hi[1] >= lo[1] && hi[2] >= lo[2])) {
        OPENVDB_THROW(openvdb::ValueError, "cannot place a camera around bounds " << lo << " - "
            << hi);
    }
    if (!(aspect > 0.0) || !std::isfinite(aspect)) {
        OPENVDB_THROW(openvdb::ValueError, "aspect ratio must be positive, got " << aspect);
    }
    if (!(fov > 0.0 && fov < 180.0)) {
        OPENVDB_THROW(openvdb::ValueError, "field of view must be in (0, 180) degrees, got "
            << fov);
    }
    const Vec3d centre = (lo + hi) * 0.5, half = (hi - lo) * 0.5;
    const double tanV = std::tan(0.5 * fov * M_PI / 180.0), tanH = tanV * aspect;
    // The near face is the nearest, so its corners subtend the widest angles: it must fit.
    constexpr double margin = 1.1;
    double dist = half[2] + margin * std::max(half[1] / tanV, half[0] / tanH);
    if (!(dist > half[2])) dist = half[2] + 1.0;   // a point: any distance shows it
    Camera cam;
    cam.eye = centre - Vec3d(0.0, 0.0, dist);
    cam.target = centre;
    cam.up = Vec3d(0.0, 1.0, 0.0);
    cam.fov = fov;
    return cam;
}

// ---- per-thread tracing ------------------------------------------------------------------------

struct Renderer::LevelSetShared
{
    LevelSetIntersector intersector;
};

struct Renderer::MeshShared
{
    MeshTracer tracer;
};

struct Renderer::Tracer
{
    explicit Tracer(const Renderer& r)
        : mR(r)
    {
        if (r.mHasSurface) {
            mSurface.emplace(r.mScene.voxels().tree());
            if (r.mMesh) {
                mMesh.emplace(r.mMesh->tracer.accessor());
            } else if (r.mLevelSet) {
                // Copies share the grid; each thread needs its own accessor inside.
                mLevelSet.emplace(r.mLevelSetShared->intersector);
                mStencil.emplace(*r.mLevelSet);
            }
        }
        if (r.mHasCloud) {
            mCloud.emplace(r.mCloud.voxels().tree());
        }
        if (r.mGround) mGround.emplace(r.mGround->getConstAccessor());
        if (r.mGather) mGather.emplace(*r.mGather);
    }

    Vec3f gatherAt(const Vec3d& p, size_t v, uint64_t h, const Vec3f* smooth)
    {
        return mR.mGather->gather(p, v, h, smooth, mR.mRadiosity.rgb(v), *mGather);
    }
    Vec3f glossyAt(const Vec3d& p, size_t v, const Vec3d& toEye, uint64_t h)
    {
        return mR.mGather->glossy(p, v, toEye, h, *mGather);
    }

    // First surface hit along the world ray (eye, unit dir) within [t0, t1]: its world distance
    // and radiosity.
    bool hitSurface(const Vec3d& eye, const Vec3d& dir, double t0, double t1, double& tHit,
        Vec3f& value)
    {
        const Scene& scene = mR.mScene;
        const IndexRay ir = toIndex(scene.transform(), eye, dir);
        // A true surface (mesh or level set): the hit point p and its normal n, index space.
        Vec3d p, n;
        if (mMesh) {
            MeshTracer::Hit hit;
            if (!mR.mMesh->tracer.intersect(eye, dir, t0, t1, hit, *mMesh)) return false;
            tHit = hit.t;
            p = ir.origin + ir.dir * hit.t;
            n = hit.normal;   // world space, as the scene's normals
        } else if (mLevelSet) {
            const double len = ir.dir.length();   // index units per world unit
            const double it1 = t1 * len;
            const RayT iRay(ir.origin, ir.dir / len, t0 * len,
                std::isfinite(it1) ? it1 : std::numeric_limits<double>::max());
            double iTime = 0.0;
            if (!mLevelSet->intersectsIS(iRay, p, iTime)) return false;
            tHit = iTime / len;
            mStencil->moveTo(p);
            n = mStencil->gradient(p);
            const double nl = n.length();
            // Where the gradient vanishes no direction is preferred: plain trilinear weights.
            n = nl > 0.0 ? n / nl : Vec3d(0.0);
        } else {
            int32_t hit = -1;
            marchVoxels(*mSurface, mR.mSurfaceBox, ir.origin + Vec3d(0.5), ir.dir, t0, t1,
                [&](int32_t index, double tIn, double) {
                    hit = index;
                    tHit = tIn;
                    return false;
                });
            if (hit < 0) return false;
            p = ir.origin + ir.dir * tHit;
            value = mR.mOptions.gather > 0 ? gatherAt(p, size_t(hit), rayHash(eye, dir), nullptr)
                                           : shade(p, scene.normal(size_t(hit)), hit);
            if (mGather) value += glossyAt(p, size_t(hit), -ir.dir.unit(), rayHash(eye, dir));
            return true;
        }
        value = shade(p, Vec3f(n), -1);
        if (mR.mGather) {
            const int32_t v = nearestVoxel(p, Vec3f(n));
            // The gather's rays about the true surface's normal: the voxels' own normals
            // would show each voxel of a curved surface as a facet.
            const Vec3f smooth(n);
            if (v >= 0 && mR.mOptions.gather > 0) {
                value = gatherAt(p, size_t(v), rayHash(eye, dir),
                    n.length() > 0.0 ? &smooth : nullptr);
            }
            if (v >= 0) {
                value += glossyAt(p, size_t(v), -ir.dir.unit(), rayHash(eye, dir));
            }
        }
        return true;
    }

    // A hash of a primary ray: the same pixel sample draws the same gather every time.
    static uint64_t rayHash(const Vec3d& eye, const Vec3d& dir)
    {
        uint64_t h = 0x2545F4914F6CDD1Dull;
        for (const double x : {eye[0], eye[1], eye[2], dir[0], dir[1], dir[2]}) {
            uint64_t bits;
            std::memcpy(&bits, &x, sizeof bits);
            h = mixHash(h ^ bits);
        }
        return h;
    }

    // The surface voxel among the 2x2x2 around p nearest to it that faces along nHit (a level
    // set's hit has no voxel of its own), or -1.
    int32_t nearestVoxel(const Vec3d& p, const Vec3f& nHit)
    {
        const Vec3d fl(std::floor(p[0]), std::floor(p[1]), std::floor(p[2]));
        const Coord base{int32_t(fl[0]), int32_t(fl[1]), int32_t(fl[2])};
        int32_t best = -1;
        double bestD = 1e300;
        for (int d = 0; d < 8; ++d) {
            const Coord c = base.offsetBy(d & 1, (d >> 1) & 1, (d >> 2) & 1);
            const int32_t i = mSurface->getValue(c);
            if (i < 0 || !(mR.mScene.normal(size_t(i)).dot(nHit) > 0.f)) continue;
            const double dist = (c.asVec3d() - p).lengthSqr();
            if (dist < bestD) { bestD = dist; best = i; }
        }
        return best;
    }

    // Radiosity at index-space point p of a surface whose normal there is nHit (see the header).
    Vec3f shade(const Vec3d& p, const Vec3f& nHit, int32_t hitVoxel)
    {
        const Scene& scene = mR.mScene;
        const Vec3d fl(std::floor(p[0]), std::floor(p[1]), std::floor(p[2]));
        const Coord base{int32_t(fl[0]), int32_t(fl[1]), int32_t(fl[2])};
        const Vec3d f = p - fl;
        Vec3d sum(0.0);
        double wsum = 0.0, bestTri = -1.0;
        int32_t best = hitVoxel;
        for (int dx = 0; dx < 2; ++dx) {
            for (int dy = 0; dy < 2; ++dy) {
                for (int dz = 0; dz < 2; ++dz) {
                    const int32_t i = mSurface->getValue(base.offsetBy(dx, dy, dz));
                    if (i < 0) continue;
                    const double tri = (dx ? f[0] : 1.0 - f[0]) * (dy ? f[1] : 1.0 - f[1])
                        * (dz ? f[2] : 1.0 - f[2]);
                    if (hitVoxel < 0 && tri > bestTri) { best = i; bestTri = tri; }
                    const double w = tri * std::max(0.0, double(scene.normal(size_t(i)).dot(nHit)));
                    if (w > 0.0) {
                        sum += Vec3d(mR.mRadiosity.rgb(size_t(i))) * w;
                        wsum += w;
                    }
                }
            }
        }
        if (wsum > 0.0) return Vec3f(sum / wsum);
        if (best >= 0) return mR.mRadiosity.rgb(size_t(best));
        return Vec3f(0.f);   // a level-set crossing with no surface voxel around it
    }

    // Emission and absorption through the cloud along [t0, t1] (world distances): adds the
    // light it sends towards the eye to L and multiplies T by the transmittance.
    void throughCloud(const Vec3d& eye, const Vec3d& dir, double t0, double t1, Vec3d& L,
        Vec3d& T)
    {
        mR.mShading->march(*mCloud, eye, dir, t0, t1, L, T, kOpaque);
    }

    // The ground under a cloud (the cloud solver's `ground_irradiance`), seen from above on the
    // top face of its layer of voxels: its radiosity rho E.
    bool hitGround(const Vec3d& eye, const Vec3d& dir, double t0, double t1, double& tHit,
        Vec3f& value)
    {
        const int up = mR.mGroundUp;
        const IndexRay ir = toIndex(mR.mGround->transform(), eye, dir);
        if (!(ir.dir[up] < 0.0)) return false;
        const double t = (mR.mGroundLayer + 0.5 - ir.origin[up]) / ir.dir[up];
        if (!(t > t0 && t < t1)) return false;
        const Vec3d p = ir.origin + ir.dir * t;
        Coord c;
        for (int k = 0; k < 3; ++k) {
            c[k] = k == up ? mR.mGroundLayer : int32_t(std::floor(p[k] + 0.5));
        }
        float E = 0.f;
        if (!mGround->probeValue(c, E)) return false;
        tHit = t;
        value = Vec3f(mR.mGroundAlbedo * E);
        return true;
    }

    Vec3f radiance(const RayT& ray, float& coverage)
    {
        const Vec3d eye = ray.eye(), dir = ray.dir();
        const double t0 = ray.t0(), t1 = ray.t1();
        double tHit = kInf;
        Vec3f surface(0.f);
        const bool hit = (mR.mHasSurface && hitSurface(eye, dir, t0, t1, tHit, surface))
            || (mR.mGround && hitGround(eye, dir, t0, t1, tHit, surface));
        Vec3d L(0.0), T(1.0);
        if (mR.mHasCloud) throughCloud(eye, dir, t0, hit ? tHit : t1, L, T);
        for (int c = 0; c < 3; ++c) {
            if (T[c] < kOpaque) T[c] = 0.0;
        }
        const Vec3f behind = hit ? surface
            : mR.mOptions.sky.empty() ? mR.mOptions.background
                                      : Vec3f(mR.mOptions.sky.radiance(dir) * kPi);
        coverage = hit ? 1.f : float(1.0 - (T[0] + T[1] + T[2]) / 3.0);
        const Vec3d b(behind);
        return Vec3f(L + Vec3d(b[0] * T[0], b[1] * T[1], b[2] * T[2]));
    }

    const Renderer& mR;
    std::optional<Accessor> mSurface, mCloud;
    std::optional<openvdb::FloatGrid::ConstAccessor> mGround;
    std::optional<MeshTracer::Accessor> mMesh;
    std::optional<FinalGather::Workspace> mGather;
    std::optional<LevelSetIntersector> mLevelSet;
    std::optional<openvdb::math::BoxStencil<openvdb::FloatGrid>> mStencil;
};

// ---- the renderer ------------------------------------------------------------------------------

Renderer::Renderer(const openvdb::GridPtrVec& grids, const RenderOptions& options,
    openvdb::util::NullInterrupter* interrupt)
    : mOptions(options)
{
    if (options.width < 1 || options.width > 16384 || options.height < 1
        || options.height > 16384) {
        OPENVDB_THROW(openvdb::ValueError, "image size must be 1..16384 pixels each way, got "
            << options.width << " x " << options.height);
    }
    if (options.samplesPerPixel < 1 || options.samplesPerPixel > 16) {
        OPENVDB_THROW(openvdb::ValueError, "samples per pixel must be in 1..16 (n gives n x n "
            "samples), got " << options.samplesPerPixel);
    }
    if (options.gather < 0 || options.gather > 65536 || options.directSamples < 1
        || options.directSamples > 65536) {
        OPENVDB_THROW(openvdb::ValueError, "gather rays must be in 0..65536 and direct-light "
            "samples in 1..65536, got " << options.gather << " and " << options.directSamples);
    }
    if (options.glossyRays < 0 || options.glossyRays > 65536) {
        OPENVDB_THROW(openvdb::ValueError, "glossy rays must be in 0..65536, got "
            << options.glossyRays);
    }
    if (!finite(options.background)) {
        OPENVDB_THROW(openvdb::ValueError, "background has a NaN or infinite value "
            << options.background);
    }
    if (options.camera) checkCamera(*options.camera);

    const openvdb::GridBase::ConstPtr radiosity = findGrid(grids, names::kRadiosity);
    const GridRoles roles = identifyRoles(grids, options.scene.surface, options.cloud.density);
    if (!radiosity && !roles.density) {
        OPENVDB_THROW(openvdb::ValueError, "no radiosity grid: solve the scene first (vdbrad "
            "solve IN OUT), then render the solved file");
    }

    if (radiosity) {
        setSurface(grids, roles, radiosity, interrupt);
    } else if (roles.surface) {
        mWarnings.push_back("surface '" + roles.surface->getName() + "' not shown: no radiosity "
            "grid (solve the scene first)");
    }

    if (options.mesh && !mHasSurface) {
        OPENVDB_THROW(openvdb::ValueError, "a mesh shows a solved surface, and the file has none");
    }
    if (roles.density) setCloud(grids, interrupt);

    const double aspect = double(options.width) / double(options.height);
    mCamera = options.camera ? *options.camera : defaultCamera(mWorldBounds, aspect);
    mForward = (mCamera.target - mCamera.eye).unit();
    mRight = mForward.cross(mCamera.up).unit();   // right-handed: along +z, y up, right is -x
    mUp = mRight.cross(mForward);
    mTanHalf = std::tan(0.5 * mCamera.fov * M_PI / 180.0);
    mAspect = aspect;
    if (mShading) mShading->aim(mCamera.eye, interrupt);
}

Renderer::~Renderer() = default;

void
Renderer::setSurface(const openvdb::GridPtrVec& grids, const GridRoles& roles,
    const openvdb::GridBase::ConstPtr& radiosity, openvdb::util::NullInterrupter* interrupt)
{
    if (!radiosity->isType<openvdb::FloatGrid>() && !radiosity->isType<openvdb::Vec3SGrid>()) {
        OPENVDB_THROW(openvdb::TypeError, "grid 'radiosity' has type "
            << radiosity->valueType() << ", expected float or vec3s");
    }
    mScene = buildScene(grids, mOptions.scene, interrupt);
    const std::string advice = "render with the same --surface and --separation as the solve";
    if (radiosity->transform() != mScene.transform()) {
        OPENVDB_THROW(openvdb::ValueError, "the radiosity grid is not on the transform of the "
            "surface '" << mScene.surfaceName() << "': " << advice);
    }
    const size_t missing = radiosity->isType<openvdb::FloatGrid>()
        ? missingVoxels(static_cast<const openvdb::FloatGrid&>(*radiosity), mScene.voxels())
        : missingVoxels(static_cast<const openvdb::Vec3SGrid&>(*radiosity), mScene.voxels());
    const openvdb::Index64 active = radiosity->activeVoxelCount();
    if (missing > 0 || active != mScene.size()) {
        OPENVDB_THROW(openvdb::ValueError, "the radiosity grid's " << active
            << " active voxels are not the " << mScene.size() << " surface voxels of '"
            << mScene.surfaceName() << "' (" << missing << " surface voxels have no value): "
            << advice);
    }
    if (openvdb::util::wasInterrupted(interrupt)) throw Cancelled("render set-up");
    mRadiosity = Attribute::sample(*radiosity, mScene.voxels(), names::kRadiosity,
        std::numeric_limits<float>::lowest());
    // Glossy: the lobes' exitance leaves the voxels' values, and is drawn view-dependent.
    const openvdb::GridBase::ConstPtr specular = findGrid(grids, names::kSpecularRadiosity);
    const bool glossy = specular && mScene.isGlossy() && mOptions.glossyRays > 0;
    // The gather reads the total radiosity (its `reflected`): made before the lobes leave.
    if (mOptions.gather > 0 || glossy) mGather.reset(new FinalGather(mScene, mRadiosity, mOptions));
    if (glossy) {
        if (specular->transform() != mScene.transform()) {
            OPENVDB_THROW(openvdb::ValueError, "the specular_radiosity grid is not on the "
                "transform of the surface '" << mScene.surfaceName() << "': " << advice);
        }
        const Attribute lobes = Attribute::sample(*specular, mScene.voxels(),
            names::kSpecularRadiosity, 0.f);
        const openvdb::Metadata::ConstPtr model = radiosity->getMetadata<openvdb::StringMetadata>(
            meta::kBrdf);
        mGather->addLobes(model ? brdfModelFromName(model->str()) : BrdfModel::Phong);
        std::vector<Vec3f> diffuse(mScene.size());
        for (size_t i = 0; i < diffuse.size(); ++i) {
            diffuse[i] = mRadiosity.rgb(i) - lobes.rgb(i);
        }
        const bool rgb = mRadiosity.isRgb() || lobes.isRgb();
        if (rgb) {
            mRadiosity = Attribute::fromRgb(std::move(diffuse));
        } else {
            std::vector<float> grey(diffuse.size());
            for (size_t i = 0; i < grey.size(); ++i) grey[i] = diffuse[i][0];
            mRadiosity = Attribute::fromGrey(std::move(grey));
        }
    }
    if (mScene.surfaceKind() == GridRoles::SurfaceKind::LevelSet) {
        // The grid the scene was built from: identifyRoles picks it by type and class, and
        // another grid of the file may carry the same name (found by fuzz_scene: looking it
        // up by name cast an Int32 grid to a level set).
        const auto ls = openvdb::gridConstPtrCast<openvdb::FloatGrid>(roles.surface);
        if (!ls) OPENVDB_THROW(openvdb::TypeError, "the surface is not a float level set");
        // A shallow copy: the tree is shared; only the class changes, for grids whose
        // exporter dropped it (the contract accepts them when named).
        mLevelSet = std::const_pointer_cast<openvdb::FloatGrid>(ls->copy());
        mLevelSet->setGridClass(openvdb::GRID_LEVEL_SET);
        try {
            mLevelSetShared.reset(new LevelSetShared{LevelSetIntersector(*mLevelSet)});
        } catch (const openvdb::Exception& e) {
            OPENVDB_THROW(openvdb::ValueError, "level set '" << mScene.surfaceName()
                << "' cannot be ray traced: " << errorMessage(e));
        }
    }
    mHasSurface = true;
    mSurfaceBox = mScene.voxels().bbox();
    mWorldBounds = worldBoundsOf(mSurfaceBox, mScene.transform());
    if (mOptions.mesh) setMesh(*mOptions.mesh);
}

void
Renderer::setCloud(const openvdb::GridPtrVec& grids, openvdb::util::NullInterrupter* interrupt)
{
    if (mOptions.cloudSource.empty()) {
        OPENVDB_THROW(openvdb::ValueError, "the cloud source grid name is empty");
    }
    const openvdb::GridBase::ConstPtr J = findGrid(grids, mOptions.cloudSource);
    // The emission as the solve read it (its options are in the solved grid).
    mCloud = buildCloud(grids, J ? emissionAsSolved(*J, mOptions.cloud) : mOptions.cloud,
        interrupt);
    if (J) {
        const auto& density = *findGrid(grids, mOptions.cloud.density);
        if (J->transform() != density.transform()) {
            OPENVDB_THROW(openvdb::ValueError, "cloud source '" << mOptions.cloudSource
                << "' is not on the transform of '" << mOptions.cloud.density << "'");
        }
    } else {
        mWarnings.push_back("cloud '" + mOptions.cloud.density + "' has no source grid '"
            + mOptions.cloudSource + "': rendered absorbing only (solve the cloud first)");
    }
    // Surfaces on the cloud's transform (a fog solved in a scene) stop the sun's light.
    const VoxelIndex* blockers = mHasSurface && mScene.transform() == mCloud.transform()
        ? &mScene.voxels() : nullptr;
    mShading.reset(new CloudShading(mCloud, J, grids, mOptions.cloudStep,
        mOptions.cloudSourceOrder, blockers, interrupt));
    mHasCloud = true;
    mCloudBox = mCloud.voxels().bbox();
    openvdb::BBoxd b = worldBoundsOf(mCloudBox, mCloud.transform());
    // A ground under the cloud (CloudTransfer::groundGrid): a float grid one voxel thick,
    // its albedo and vertical axis in its metadata.
    const openvdb::GridBase::ConstPtr ground = findGrid(grids, "ground_irradiance");
    if (ground && ground->isType<openvdb::FloatGrid>() && ground->activeVoxelCount() > 0) {
        const auto albedo = ground->getMetadata<openvdb::FloatMetadata>("vdbrad:ground_albedo");
        const auto up = ground->getMetadata<openvdb::Int32Metadata>("vdbrad:up");
        const openvdb::CoordBBox box = ground->evalActiveVoxelBoundingBox();
        if (albedo && up && up->value() >= 0 && up->value() <= 2
            && box.dim()[up->value()] == 1
            && ground->transform() == findGrid(grids, mOptions.cloud.density)->transform()) {
            mGround = openvdb::gridConstPtrCast<openvdb::FloatGrid>(ground);
            mGroundAlbedo = albedo->value();
            mGroundUp = up->value();
            mGroundLayer = box.min()[mGroundUp];
            b.expand(worldBoundsOf(box, mCloud.transform()));
        } else {
            mWarnings.push_back("'ground_irradiance' not shown: not a cloud solver's ground "
                "on the cloud's transform");
        }
    }
    if (mHasSurface) mWorldBounds.expand(b);
    else mWorldBounds = b;
}

void
Renderer::setMesh(const TriangleMesh& mesh)
{
    // Cells of four voxels: a few triangles each for meshes about as fine as the voxels.
    const double voxel = mScene.transform().voxelSize()[0];
    mMesh.reset(new MeshShared{MeshTracer(mesh, 4.0 * voxel)});
    const openvdb::BBoxd& b = mMesh->tracer.bounds();
    if (mMesh->tracer.triangleCount() == 0) {
        OPENVDB_THROW(openvdb::ValueError, "the mesh has no triangle of non-zero area");
    }
    // The voxels' cubes hold every point of the mesh they were made from (to rounding).
    const double slack = 0.25 * voxel;
    const openvdb::BBoxd& v = mWorldBounds;
    for (int k = 0; k < 3; ++k) {
        if (b.min()[k] + slack < v.min()[k] || b.max()[k] - slack > v.max()[k]) {
            OPENVDB_THROW(openvdb::ValueError, "the mesh (bounds " << b.min() << " - " << b.max()
                << ") is not within the surface's voxels (" << v.min() << " - " << v.max()
                << "): give the mesh the scene was voxelised from");
        }
    }
}

Renderer::RayT
Renderer::primaryRay(double x, double y) const
{
    const double u = (2.0 * x / double(mOptions.width) - 1.0) * mTanHalf * mAspect;
    const double v = (1.0 - 2.0 * y / double(mOptions.height)) * mTanHalf;
    const Vec3d dir = (mForward + mRight * u + mUp * v).unit();
    return RayT(mCamera.eye, dir, 0.0, kInf);
}

Vec3f
Renderer::radiance(const RayT& worldRay, float* coverage) const
{
    Tracer tracer(*this);
    float c = 0.f;
    const Vec3f L = tracer.radiance(worldRay, c);
    if (coverage) *coverage = c;
    return L;
}

Image
Renderer::render(openvdb::util::NullInterrupter* interrupt) const
{
    const int W = mOptions.width, H = mOptions.height, n = mOptions.samplesPerPixel;
    Image image;
    image.width = W;
    image.height = H;
    image.pixels.assign(size_t(W) * size_t(H), Vec3f(0.f));
    image.coverage.assign(size_t(W) * size_t(H), 0.f);
    image.warnings = mWarnings;
    std::atomic<int> rowsDone{0};
    std::atomic<bool> cancelled{false};
    const double inv = 1.0 / double(n * n);
    tbb::parallel_for(tbb::blocked_range<int>(0, H), [&](const tbb::blocked_range<int>& rows) {
        if (cancelled) return;
        Tracer tracer(*this);
        for (int y = rows.begin(); y != rows.end(); ++y) {
            for (int x = 0; x < W; ++x) {
                Vec3d sum(0.0);
                double cov = 0.0;
                for (int sy = 0; sy < n; ++sy) {
                    for (int sx = 0; sx < n; ++sx) {
                        float c = 0.f;
                        sum += Vec3d(tracer.radiance(primaryRay(x + (sx + 0.5) / n,
                            y + (sy + 0.5) / n), c));
                        cov += c;
                    }
                }
                const size_t at = size_t(y) * size_t(W) + size_t(x);
                image.pixels[at] = Vec3f(sum * inv);
                image.coverage[at] = float(cov * inv);
            }
            const int done = ++rowsDone;
            if (openvdb::util::wasInterrupted(interrupt, int(int64_t(100) * done / H))) {
                cancelled = true;
                return;
            }
        }
    });
    if (cancelled) throw Cancelled("render");
    return image;
}

Image
renderImage(const openvdb::GridPtrVec& grids, const RenderOptions& options,
    openvdb::util::NullInterrupter* interrupt)
{
    // end() also when an exception leaves, so a progress bar is always closed.
    struct Scope
    {
        openvdb::util::NullInterrupter* i;
        ~Scope() { if (i) i->end(); }
    } scope{interrupt};
    if (interrupt) interrupt->start("rendering");
    const Renderer renderer(grids, options, interrupt);
    return renderer.render(interrupt);
}

} // namespace vdbrad
