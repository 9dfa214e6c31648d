#include "vdbrad/render/FinalGather.h"

#include "vdbrad/core/Constants.h"
#include "vdbrad/core/SampleHash.h"
#include "vdbrad/glossy/ControlPoints.h"
#include "vdbrad/surface/SurfaceRays.h"

#include <algorithm>
#include <cmath>
#include <utility>

namespace vdbrad {

using openvdb::Vec3d;
using openvdb::Vec3f;

namespace {

DirectLightOptions
directOptionsOf(const RenderOptions& options)
{
    DirectLightOptions d;
    d.samples = options.directSamples;
    d.sun = options.sun;
    return d;
}

} // namespace

FinalGather::FinalGather(const Scene& scene, const Attribute& radiosity,
    const RenderOptions& options)
    : mScene(scene)
    , mOptions(options)
    , mEmitters(scene)
    , mRegions(findRegions(scene.voxels(), scene.normals(), LineType::Naive))
    , mSampler(scene, mEmitters, directOptionsOf(options),
          mRegions.cavities > 0 ? &mRegions.region : nullptr)
    , mBox(scene.voxels().bbox())
{
    mReflected.resize(scene.size());
    for (size_t i = 0; i < scene.size(); ++i) {
        mReflected[i] = Vec3d(radiosity.rgb(i)) - Vec3d(scene.emission().rgb(i));
    }
}

void
FinalGather::addLobes(BrdfModel model)
{
    mLobes.reset(new GlossyLamps(mScene, mSampler, model));
}

FinalGather::Workspace::Workspace(const FinalGather& g)
    : surface(g.mScene.voxels().tree())
    , direct(g.mSampler)
    , lobeDirect(g.mSampler)
{
}

Vec3d
FinalGather::onPlane(const Vec3d& p, size_t v) const
{
    const Vec3d c = mScene.voxels().coord(v).asVec3d();
    const Vec3d n(mScene.normal(v));
    Vec3d q = p - n * (p - mSampler.planes().point(v)).dot(n);
    for (int k = 0; k < 3; ++k) q[k] = std::clamp(q[k], c[k] - 0.5, c[k] + 0.5);
    return q;
}

Vec3f
FinalGather::glossy(const Vec3d& p, size_t v, const Vec3d& toEye, uint64_t h,
    Workspace& ws) const
{
    const Vec3f ks = mScene.specular().rgb(v);
    if (!mLobes || ks == Vec3f(0.f)) return Vec3f(0.f);
    const SurfacePlanes& planes = mSampler.planes();
    const Vec3d n(mScene.normal(v));
    const openvdb::math::Mat3d R = ControlPoints::frame(n);
    auto local = [&](const Vec3d& w) { return w * R; };   // R^T w
    const Vec3d wo = local(toEye);
    if (wo.z() <= 0.0) return Vec3f(0.f);
    const Brdf& brdf = mLobes->lobe(mScene.roughness().grey(v));
    const Vec3d q = onPlane(p, v);
    // The lamps: pi lobe(l, wo) times the irradiance arriving from l.
    std::vector<std::pair<Vec3d, Vec3d>> incident;
    ws.lobeDirect.incident = &incident;
    mSampler.at(q, n, v, mixHash(h + 11), ws.lobeDirect);
    Vec3d sum(0.0);
    for (const auto& [l, e] : incident) sum += e * (kPi * brdf.value(local(l), wo));
    // The rest: directions drawn from the lobe, each worth lobe cos / pdf of what it hits.
    const size_t N = size_t(mOptions.glossyRays);
    const bool closed = mRegions.region.empty() ? false : mRegions.region[v] != 0;
    const Vec3d origin = planes.rayOrigin(v, q);
    Vec3d gathered(0.0);
    size_t used = 0;
    const double phase = unitHash(mixHash(h + 12));
    for (size_t s = 0; s < N; ++s) {
        const double u1 = (double(s) + unitHash(mixHash(h + 13 + 2 * s))) / double(N);
        const double u2 = std::fmod(phase + 0.6180339887498949 * double(s), 1.0);
        double pdf = 0.0;
        const Vec3d l = brdf.sample(wo, u1, u2, pdf);
        ++used;
        if (l.z() <= 0.0 || !(pdf > 0.0)) continue;
        const Vec3d world = R * l;
        const uint32_t hit = traceSurface(mScene, planes, ws.surface, mBox, uint32_t(v), origin,
            world);
        if (hit == kRaySky && closed) { --used; continue; }   // a digitisation crack
        if (hit < kRayBack) {
            gathered += mLobes->sent(hit, -world, mReflected[hit])
                * (brdf.value(l, wo) * l.z() / pdf);
        } else if (hit == kRaySky && !mOptions.sky.empty()) {
            // The sky the file was solved under, pi L as everything here (radiosity).
            gathered += mOptions.sky.radiance(mScene.transform().baseMap()->applyJacobian(world))
                * (kPi * brdf.value(l, wo) * l.z() / pdf);
        }
    }
    if (used > 0) sum += gathered / double(used);
    return Vec3f(float(ks[0] * sum[0]), float(ks[1] * sum[1]), float(ks[2] * sum[2]));
}

Vec3f
FinalGather::gather(const Vec3d& p, size_t v, uint64_t h, const Vec3f* smooth,
    const Vec3f& solved, Workspace& ws) const
{
    const SurfacePlanes& planes = mSampler.planes();
    const Vec3d n(mScene.normal(v));
    const Vec3d q = onPlane(p, v);
    const Vec3d direct = mSampler.at(q, n, v, mixHash(h), ws.direct);
    const size_t N = size_t(mOptions.gather);
    const CosineRays rays(smooth ? *smooth : mScene.normal(v), mixHash(h + 1), N);
    const bool closed = mRegions.region.empty() ? false : mRegions.region[v] != 0;
    const Vec3d origin = planes.rayOrigin(v, q);   // as shadow rays
    Vec3d sum(0.0);
    size_t used = 0;
    for (size_t s = 0; s < N; ++s) {
        const uint32_t hit = traceSurface(mScene, planes, ws.surface, mBox, uint32_t(v), origin,
            rays(s));
        // A closed room's voxel leaving through its own cube, or a ray from a curved surface's
        // voxel meeting the back of its neighbour: digitisation cracks.
        if ((hit == kRaySky && closed) || hit == kRayBack) continue;
        if (hit == kRaySky && !mOptions.sky.empty()) {
            sum += mOptions.sky.radiance(mScene.transform().baseMap()->applyJacobian(rays(s)))
                * kPi;
        } else if (hit < kRayBack) {
            sum += mLobes ? mLobes->sent(hit, -rays(s), mReflected[hit]) : mReflected[hit];
        }
        ++used;
    }
    // Every ray through a crack (a voxel between curved neighbours): its solved radiosity.
    if (used == 0 && N > 0) return solved;
    const Vec3d gathered = used > 0 ? sum / double(used) : Vec3d(0.0);
    const Vec3d rho(mScene.albedo().rgb(v)), e(mScene.emission().rgb(v));
    return Vec3f(e + Vec3d(rho[0] * (direct[0] + gathered[0]), rho[1] * (direct[1] + gathered[1]),
        rho[2] * (direct[2] + gathered[2])));
}

} // namespace vdbrad
