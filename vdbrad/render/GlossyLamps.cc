#include "vdbrad/render/GlossyLamps.h"

#include "vdbrad/core/Constants.h"
#include "vdbrad/core/SampleHash.h"
#include "vdbrad/glossy/ControlPoints.h"
#include "vdbrad/glossy/GlossySurfaces.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace vdbrad {

namespace {
using openvdb::Vec3d;
using openvdb::Vec3f;
} // namespace

GlossyLamps::GlossyLamps(const Scene& scene, const DirectLightSampler& sampler, BrdfModel model)
    : mScene(scene)
{
    const size_t n = scene.size();
    for (size_t v = 0; v < n; ++v) {
        if (scene.specular().rgb(v) == Vec3f(0.f)) continue;
        const long k = GlossySurfaces::roughnessKey(scene.roughness().grey(v));
        if (mLobes.count(k) == 0) mLobes.emplace(k, Brdf(model, GlossySurfaces::roughnessOf(k)));
    }
    std::vector<std::vector<std::pair<Vec3d, Vec3d>>> found(n);
    mLampShare.assign(n, Vec3d(0.0));
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n),
        [&](const tbb::blocked_range<size_t>& r) {
            DirectLightSampler::Workspace work(sampler);
            for (size_t v = r.begin(); v != r.end(); ++v) {
                const Vec3f ks = scene.specular().rgb(v);
                if (ks == Vec3f(0.f)) continue;
                const Vec3d nrm(scene.normal(v));
                const openvdb::math::Mat3d R = ControlPoints::frame(nrm);
                work.incident = &found[v];
                // Hashed from the voxel: the same arrivals for every pixel and thread.
                sampler.at(sampler.planes().point(v), nrm, v, mixHash(v ^ 0x9e3779b97f4a7c15ull),
                    work);
                for (auto& [l, e] : found[v]) {
                    l = l * R;   // R^T l: the local frame
                    mLampShare[v] += Vec3d(ks[0] * e[0], ks[1] * e[1], ks[2] * e[2]);
                }
            }
        });
    mStart.assign(n + 1, 0);
    for (size_t v = 0; v < n; ++v) mStart[v + 1] = mStart[v] + uint32_t(found[v].size());
    mLamps.reserve(mStart[n]);
    for (const auto& f : found) mLamps.insert(mLamps.end(), f.begin(), f.end());
}

const Brdf&
GlossyLamps::lobe(float roughness) const
{
    return mLobes.at(GlossySurfaces::roughnessKey(roughness));
}

Vec3d
GlossyLamps::sent(size_t v, const Vec3d& out, const Vec3d& reflected) const
{
    const Vec3f ks = mScene.specular().rgb(v);
    if (ks == Vec3f(0.f)) return reflected;
    const Vec3d wo = out * ControlPoints::frame(Vec3d(mScene.normal(v)));   // R^T out
    const Vec3d even = reflected - mLampShare[v];
    if (wo.z() <= 0.0) return even;
    const Brdf& brdf = lobe(mScene.roughness().grey(v));
    Vec3d lamp(0.0);
    for (uint32_t e = mStart[v]; e < mStart[v + 1]; ++e) {
        lamp += mLamps[e].second * (kPi * brdf.value(mLamps[e].first, wo));
    }
    return even + Vec3d(ks[0] * lamp[0], ks[1] * lamp[1], ks[2] * lamp[2]);
}

} // namespace vdbrad
