// A radiosity solve's checkpoint (Checkpoint.h): the hash of what changes its iterates, and
// everything the next iteration reads, saved and restored to the same bits.
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/surface/RadiositySolverImpl.h"

#include "vdbrad/core/Precision.h"
#include "vdbrad/glossy/GlossySurfaces.h"

#include <cstring>
#include <string>
#include <type_traits>

namespace vdbrad {

using namespace detail;   // Precision.h: the state types

uint64_t
RadiositySolver::fingerprint() const
{
    const VoxelIndex& v = mScene.voxels();
    uint64_t h = hashBytes("vdbrad solve", 12);
    h = hashBytes(v.coords().data(), v.size() * sizeof(openvdb::Coord), h);
    h = hashBytes(mScene.normals().data(), mScene.size() * sizeof(openvdb::Vec3f), h);
    h = mScene.albedo().hash(h);
    h = mScene.emission().hash(h);
    if (mScene.hasEmissionArea()) h = mScene.emissionArea().hash(h);
    const int64_t options[8] = {mOptions.directions, int64_t(mOptions.lines),
        int64_t(mOptions.update), int64_t(mOptions.visibility), int64_t(mOptions.accelerate),
        mOptions.andersonDepth, int64_t(directions().size()), int64_t(mImpl->wide)};
    h = hashBytes(options, sizeof options, h);
    if (mImpl->exact) {
        // Only an exact-direct solve's state is R rather than B (older fingerprints unchanged).
        const int64_t direct[2] = {1, mOptions.directSamples};
        h = hashBytes(direct, sizeof direct, h);
    }
    // Only solves with a sky hash it (older fingerprints unchanged).
    if (!mOptions.sky.empty()) h = mOptions.sky.hash(h);
    if (const auto& sun = mOptions.sun) {
        // Only solves with a sun hash it (older fingerprints unchanged).
        const double light[7] = {sun->zenith, sun->azimuth, double(sun->up),
            sun->irradiance[0], sun->diameter, sun->irradiance[1], sun->irradiance[2]};
        h = hashBytes(light, sizeof light, h);
    }
    if (mImpl->glossy) {
        // Only glossy solves hash their lobes (older fingerprints unchanged).
        h = mScene.specular().hash(h);
        h = mScene.roughness().hash(h);
        const GlossyOptions& g = mOptions.glossy;
        const int64_t glossy[4] = {g.controlPoints, int64_t(g.model), int64_t(g.rotation),
            int64_t(g.fit)};
        h = hashBytes(glossy, sizeof glossy, h);
        if (g.basis == GlossyBasis::Harmonics) {
            const int64_t harmonics[2] = {int64_t(g.basis), g.harmonicOrder};
            h = hashBytes(harmonics, sizeof harmonics, h);
        }
    }
    return hashBytes(&mOptions.occlusionDepth, sizeof(float), h);
}

void
RadiositySolver::saveState(SolverState& state) const
{
    const Impl& impl = *mImpl;
    mIteration.save(state);
    const uint8_t flags[2] = {uint8_t(impl.hitsKnown), uint8_t(impl.gatheredStale)};
    state.put("flags", flags, 2);
    state.put("invZ", impl.invZ);
    if (!mOptions.sky.empty()) state.put("sky", impl.skyIn);
    impl.withState(impl.rgb, [&](const auto& st) {
        using StateT = std::decay_t<decltype(st)>;
        using Scalar = typename StateT::Scalar;
        // Arrays of channels, in the state's precision.
        auto put = [&](const std::string& name, const auto& v) {
            state.put(name, reinterpret_cast<const Scalar*>(v.data()), v.size() * StateT::kWidth);
        };
        put("B", st.B);
        put("unshot", st.unshot);
        for (size_t g = 0; g < size_t(kGroups); ++g) {
            put("gathered" + std::to_string(g), g < st.gathered.size()
                ? st.gathered[g] : typename decltype(st.gathered)::value_type());
        }
        if (st.mixer) st.mixer->save(state, "anderson.");
        if (impl.glossy) {
            put("glossy.spec", st.spec);
        }
    });
    if (impl.glossy) {
        state.put("glossy.share", impl.glossyShare);
        state.put("glossy.direct", reinterpret_cast<const float*>(impl.glossyDirect.data()),
            impl.glossyDirect.size() * 3);
        state.put("glossy.sky", reinterpret_cast<const float*>(impl.glossySkyIn.data()),
            impl.glossySkyIn.size() * 3);
    }
}

void
RadiositySolver::restoreState(const SolverState& state)
{
    Impl& impl = *mImpl;
    const size_t n = mScene.size();
    mIteration.restore(state);
    const std::vector<uint8_t> flags = state.get<uint8_t>("flags", 2);
    impl.hitsKnown = flags[0] != 0;
    impl.gatheredStale = flags[1] != 0;
    impl.invZ = state.get<double>("invZ", n);
    if (!mOptions.sky.empty()) {
        impl.skyIn = state.get<float>("sky");
        if (!impl.skyIn.empty() && impl.skyIn.size() != n * (impl.rgb ? 3 : 1)) {
            OPENVDB_THROW(openvdb::ValueError, "checkpoint's sky light does not fit the scene");
        }
    }
    impl.withState(impl.rgb, [&](auto& st) {
        using StateT = std::decay_t<decltype(st)>;
        using Scalar = typename StateT::Scalar;
        constexpr size_t width = StateT::kWidth;
        // Arrays of channels, empty or of `count` values (n voxels; for glossy voxels, their
        // control values).
        auto get = [&](const std::string& name, auto& v, size_t count, const char* unit) {
            const std::vector<Scalar> f = state.get<Scalar>(name);
            if (!f.empty() && f.size() != count * width) {
                OPENVDB_THROW(openvdb::ValueError, "checkpoint's '" << name << "' has "
                    << f.size() << " values for " << count << " " << unit);
            }
            v.resize(f.size() / width);
            if (!f.empty()) {
                std::memcpy(static_cast<void*>(v.data()), f.data(), f.size() * sizeof(Scalar));
            }
        };
        get("B", st.B, n, "voxels");
        get("unshot", st.unshot, n, "voxels");
        st.gathered.resize(size_t(kGroups));
        for (size_t g = 0; g < st.gathered.size(); ++g) {
            get("gathered" + std::to_string(g), st.gathered[g], n, "voxels");
        }
        if (st.B.size() != n) OPENVDB_THROW(openvdb::ValueError, "checkpoint has no B");
        impl.startFromSource = false;
        if (st.mixer) st.mixer->restore(state, "anderson.");
        if (impl.glossy) {
            const size_t m = impl.glossy->size() * impl.glossy->points();
            get("glossy.spec", st.spec, m, "control values");
            if (st.spec.size() != m) {
                OPENVDB_THROW(openvdb::ValueError, "checkpoint has no glossy light");
            }
        }
    });
    if (impl.glossy) {
        const size_t m = impl.glossy->size() * impl.glossy->points();
        impl.glossyShare = state.get<double>("glossy.share");
        if (!impl.glossyShare.empty() && impl.glossyShare.size() != m) {
            OPENVDB_THROW(openvdb::ValueError, "checkpoint's glossy shares do not fit the scene");
        }
        const std::vector<float> direct = state.get<float>("glossy.direct");
        if (!direct.empty() && direct.size() != 3 * m) {
            OPENVDB_THROW(openvdb::ValueError, "checkpoint's glossy direct light does not fit");
        }
        impl.glossyDirect.resize(direct.size() / 3);
        for (size_t e = 0; e < impl.glossyDirect.size(); ++e) {
            impl.glossyDirect[e] = openvdb::Vec3f(direct[3 * e], direct[3 * e + 1],
                direct[3 * e + 2]);
        }
        // (A checkpoint written before the sky existed on glossy voxels has none: "glossy.sky"
        // absent reads as empty, as for a solve without a sky.)
        const std::vector<float> sky = state.has("glossy.sky") ? state.get<float>("glossy.sky")
                                                               : std::vector<float>();
        if (!sky.empty() && sky.size() != 3 * m) {
            OPENVDB_THROW(openvdb::ValueError, "checkpoint's glossy sky light does not fit");
        }
        impl.glossySkyIn.resize(sky.size() / 3);
        for (size_t e = 0; e < impl.glossySkyIn.size(); ++e) {
            impl.glossySkyIn[e] = openvdb::Vec3f(sky[3 * e], sky[3 * e + 1], sky[3 * e + 2]);
        }
        impl.applyGlossyShares();
    }
    impl.narrowView(mScene);
}

} // namespace vdbrad
