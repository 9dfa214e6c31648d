#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/surface/RadiositySolverImpl.h"
#include "vdbrad/core/ProcessInfo.h"

#include "vdbrad/core/Denormals.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/core/Precision.h"
#include "vdbrad/core/TextFormat.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/distribute/SlabDistribution.h"
#include "vdbrad/glossy/GlossySurfaces.h"
#include "vdbrad/sweep/Enclosure.h"
#include "vdbrad/sweep/LeafOrder.h"
#include "vdbrad/sweep/LineSweep.h"
#include "vdbrad/sweep/RayCastVisibility.h"
#include "vdbrad/sweep/SweepSchedule.h"
#include "vdbrad/sweep/VisibilityCache.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <tuple>
#include <type_traits>

#include <unistd.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace vdbrad {

namespace {
using namespace detail;   // Precision.h: the state types

// The option checks of a solver (the first error, in one line), before anything is built.
void
checkOptions(const Scene& scene, const RadiosityOptions& options, bool slab)
{
    if (options.directions < 1) {
        OPENVDB_THROW(openvdb::ValueError, "directions must be >= 1, got " << options.directions);
    }
    if (options.accelerate == Acceleration::Anderson
        && options.update == UpdateScheme::Progressive) {
        OPENVDB_THROW(openvdb::ValueError, "Anderson acceleration needs Jacobi or in-place "
            "updates, not progressive shooting (whose state is not B alone)");
    }
    if (!(options.occlusionDepth > 0.f)) {
        OPENVDB_THROW(openvdb::ValueError, "occlusion depth must be > 0, got "
            << options.occlusionDepth);
    }
    if (options.directSamples < 1) {
        OPENVDB_THROW(openvdb::ValueError, "direct-light samples must be >= 1, got "
            << options.directSamples);
    }
    if (const auto& sun = options.sun) {
        if (options.direct == DirectMode::Sweep) {
            OPENVDB_THROW(openvdb::ValueError, "the sun's light is computed exactly: it does not "
                "go through the directions (direct light sweep)");
        }
        if (!(sun->zenith >= 0.0 && sun->zenith < 90.0) || !std::isfinite(sun->azimuth)
            || !(sun->irradiance[0] >= 0.0) || !(sun->irradiance[1] >= 0.0)
            || !(sun->irradiance[2] >= 0.0) || !std::isfinite(sun->irradiance.length())
            || !(sun->diameter >= 0.0 && sun->diameter <= 10.0) || sun->up < 0 || sun->up > 2) {
            OPENVDB_THROW(openvdb::ValueError, "the sun needs a zenith in [0, 90) degrees, a "
                "finite azimuth, an irradiance >= 0 and a diameter in [0, 10] degrees");
        }
    }
    if (slab) {
        // What the slab passes do not carry (SlabDistribution.h).
        auto refuse = [](const char* what) {
            OPENVDB_THROW(openvdb::ValueError, "a solve spread over slabs " << what);
        };
        if (scene.isGlossy()) refuse("needs diffuse surfaces (no `specular` grid)");
        if (options.lines != LineType::Naive) refuse("needs naive lines");
        if (options.visibility != Visibility::Sweep) refuse("needs the line sweeps");
        if (options.accelerate != Acceleration::None) refuse("is not Anderson-accelerated");
    }
    if (scene.isGlossy()) {
        // The lobes' light is carried by the sweeps only; their state is not B alone.
        if (options.update == UpdateScheme::Progressive) {
            OPENVDB_THROW(openvdb::ValueError, "glossy surfaces need Jacobi or in-place "
                "updates, not progressive shooting");
        }
        if (options.accelerate == Acceleration::Anderson) {
            OPENVDB_THROW(openvdb::ValueError, "glossy surfaces are not Anderson-accelerated "
                "(their lobes' light is not part of the mixed iterate)");
        }
        if (options.visibility == Visibility::RayCast) {
            OPENVDB_THROW(openvdb::ValueError, "glossy surfaces are solved with the line "
                "sweeps, not the ray-casting reference");
        }
    }
}

} // namespace

// Glossy voxels, once the schedule is laid out: each pattern position's glossy index, the
// points each pattern's directions splat on, and per direction its two interpolations.
void
RadiositySolver::Impl::layOutGlossySlots()
{
    const size_t P = glossy->points();
    glossySlotToward.resize(2 * schedule->directions().size());
    for (size_t p = 0; p < glossyAt.size(); ++p) {
        const SweepSchedule::Pattern& pattern = schedule->pattern(p);
        const std::vector<uint32_t>& order = pattern.order;
        if (order.empty()) continue;
        glossyAt[p].resize(order.size());
        for (size_t x = 0; x < order.size(); ++x) {
            glossyAt[p][x] = glossy->glossyOf(order[x]);
        }
        std::vector<uint32_t>& slots = glossySlots[p];
        if (glossy->harmonics()) {
            // Every direction splats on every coefficient.
            slots.resize(P);
            for (size_t j = 0; j < P; ++j) slots[j] = uint32_t(j);
            continue;
        }
        slots = GlossySurfaces::splatPoints(glossy->controlPoints(),
            schedule->directions(), pattern.directions);
        std::vector<uint32_t> slot(P, GlossySurfaces::kNone);
        for (size_t j = 0; j < slots.size(); ++j) slot[slots[j]] = uint32_t(j);
        for (const size_t k : pattern.directions) {
            for (const bool negative : {false, true}) {
                ControlPoints::Weights w = glossy->toward(k, negative);
                for (uint32_t& i : w.index) i = slot[i];
                glossySlotToward[2 * k + (negative ? 1 : 0)] = w;
            }
        }
    }
}

RadiositySolver::RadiositySolver(const Scene& scene, const RadiosityOptions& options)
    : RadiositySolver(scene, options, nullptr)
{
}

RadiositySolver::RadiositySolver(const Scene& scene, const RadiosityOptions& options,
    std::shared_ptr<const SlabContext> slab)
    : IterativeSolver(FixedPointIteration(options.maxIterations, options.tolerance,
          options.accelerate, options.andersonDepth))
    , mScene(scene)
    , mOptions(options)
    , mImpl(new Impl)
{
    checkOptions(scene, options, slab != nullptr);
    DirectionSet directions = DirectionSet::fromCount(options.directions);
    const size_t dirs = directions.size(), n = scene.size();

    Impl& impl = *mImpl;
    impl.slab = std::move(slab);
    if (impl.slab) impl.pipeline.reset(new SlabPipeline(impl.ranksFor(options)));
    if (scene.isGlossy()) impl.glossy.reset(new GlossySurfaces(scene, directions, options.glossy));
    // A cache pays from the second iteration on. Glossy senders' light depends on the
    // direction, which the cache's replay does not carry: glossy scenes sweep every time.
    // Slabs: a replay reads the B of voxels other ranks hold.
    if (options.visibilityCache > 0 && options.visibility == Visibility::Sweep
        && options.maxIterations > 1 && !impl.glossy && !impl.slab) {
        impl.cache.reset(new VisibilityCache(dirs, n, options.visibilityCache));
        impl.offered.assign(dirs, 0);
    }
    impl.coefficient.resize(dirs);
    for (size_t k = 0; k < dirs; ++k) {
        const openvdb::Coord& d = directions.direction(k);
        impl.coefficient[k] = float(directions.factor(k) / openvdb::Vec3d(d.asVec3d()).length());
    }
    // Per-voxel normalisation of the direction factors (DirectionSet.h).
    impl.invZ = directions.inverseHemisphereSums(scene.normals());
    impl.regions = impl.slab ? impl.slab->regions
                             : findRegions(scene.voxels(), scene.normals(), options.lines,
                                   kEnclosureBlocks);
    const std::vector<uint32_t>* regions = impl.regions.cavities > 0 ? &impl.regions.region
                                                                      : nullptr;
    SweepSchedule::Layout layout;
    layout.sweeps = options.visibility == Visibility::Sweep;
    layout.lines = options.lines;
    layout.normals = &scene.normals();
    layout.depth = options.occlusionDepth;
    layout.regions = regions;
    layout.frame = impl.slab ? &impl.slab->frame : nullptr;
    impl.schedule.reset(new SweepSchedule(scene.voxels(), std::move(directions), layout));
    if (impl.cache) {
        // Each accumulator group this rank sweeps keeps its share of the budget
        // (VisibilityCache::pools).
        const Distribution& ranks = impl.ranksFor(options);
        std::vector<uint32_t> groupOf(dirs, VisibilityCache::kNoPool);
        for (int g = 0; g < kGroups; ++g) {
            if (!ranks.owns(g)) continue;
            impl.schedule->forDirections(g, [&](size_t k) { groupOf[k] = uint32_t(g); });
        }
        impl.cache->pools(groupOf);
    }
    if (impl.glossy) impl.layOutGlossySlots();
    if (options.visibility == Visibility::RayCast) {
        impl.rays.reset(new RayCastVisibility(scene.voxels(), scene.normals(), options.lines,
            options.occlusionDepth, regions));
    }

    // Exact direct light: the sweeps solve R = rho (D + gathered R) for R = B - E.
    impl.source = &scene.emission();
    impl.exact = impl.slab ? impl.slab->exact
                           : usesExactDirect(options.direct, scene, bool(options.sun));
    if (impl.exact) {
        impl.emitters = impl.slab ? impl.slab->emitters : Emitters(scene);
        impl.source = &impl.reflected;   // 0 until the first iterate() computes D
        impl.startFromSource = true;
    }

    impl.wide = impl.slab ? impl.slab->wide : solvesInDouble(scene.albedo(), options.precision);
    impl.rgb = solvesRgb(scene, options);
    if (!options.sky.empty()) {
        // Each direction's cells, pi L: the sky as the radiosity a line starts with.
        impl.skyCells = options.sky.cellMeans(impl.schedule->directions(), scene.transform());
        for (openvdb::Vec3f& v : impl.skyCells) v *= float(kPi);
    }
    impl.withState(impl.rgb, [&](auto& st) {
        using StateT = std::decay_t<decltype(st)>;
        using ValueT = typename decltype(st.B)::value_type;
        st.B.resize(n);
        for (size_t i = 0; i < n; ++i) st.B[i] = value<ValueT>(*impl.source, i);
        st.mixer = mIteration.makeMixer<typename StateT::Scalar>(n * StateT::kWidth);
        if (impl.glossy) {
            st.spec.assign(impl.glossy->size() * impl.glossy->points(), ValueT(0));
        }
        // Nothing has been shot yet: all of the source (E, or rho D) is unshot.
        if (options.update == UpdateScheme::Progressive) st.unshot = st.B;
    });
    impl.narrowView(scene);
}

RadiositySolver::~RadiositySolver() = default;


void
RadiositySolver::prepareDirect(openvdb::util::NullInterrupter* interrupt)
{
    Impl& impl = *mImpl;
    if (!impl.exact || impl.directReady) return;
    const size_t n = mScene.size();
    DirectLightOptions d;
    d.samples = mOptions.directSamples;
    d.ranks = mOptions.ranks;
    d.sun = mOptions.sun;
    // Glossy voxels also need where their direct light comes from: the estimate's arrivals,
    // splatted on the points (per unit of irradiance; iterate() scales by the voxel's cosine
    // sum as the sweeps' splats are).
    IncidentSink sink;
    if (impl.glossy) {
        const GlossySurfaces& gl = *impl.glossy;
        const size_t P = gl.points();
        impl.glossyDirect.assign(gl.size() * P, openvdb::Vec3f(0.f));
        // Captures by value or of objects that outlive the call: the sink runs after this block.
        const GlossySurfaces* glp = &gl;
        sink.wants = [glp](size_t i) { return glp->glossyOf(i) != GlossySurfaces::kNone; };
        sink.take = [glp, P, &impl](size_t i,
                        const std::vector<std::pair<openvdb::Vec3d, openvdb::Vec3d>>& in) {
            const GlossySurfaces& gl = *glp;
            openvdb::Vec3f* splat = &impl.glossyDirect[size_t(gl.glossyOf(i)) * P];
            for (const auto& [dir, light] : in) gl.splat(dir, openvdb::Vec3f(light), splat);
        };
    }
    // Slabs: computed on the whole scene (solveRadiosity()).
    impl.direct = impl.slab ? impl.slab->direct
                            : directIrradiance(mScene, impl.emitters, d,
                                  impl.regions.cavities > 0 ? &impl.regions.region : nullptr,
                                  interrupt, impl.glossy ? &sink : nullptr);
    // Under MPI each rank's sink took its own voxels' arrivals (Distribution.h).
    if (!impl.glossyDirect.empty()) {
        impl.ranksFor(mOptions).combine(&impl.glossyDirect[0][0], 3 * impl.glossyDirect.size());
    }
    const std::vector<openvdb::Vec3f>& D = impl.direct.irradiance;
    if (impl.rgb) {
        std::vector<openvdb::Vec3f> v(n);
        for (size_t i = 0; i < n; ++i) v[i] = mScene.albedo().rgb(i) * D[i];
        impl.reflected = Attribute::fromRgb(std::move(v));
    } else {
        std::vector<float> v(n);
        for (size_t i = 0; i < n; ++i) v[i] = mScene.albedo().grey(i) * D[i][0];
        impl.reflected = Attribute::fromGrey(std::move(v));
    }
    impl.directReady = true;
    if (!impl.startFromSource) return;
    impl.startFromSource = false;
    impl.withState(impl.rgb, [&](auto& st) {
        using ValueT = typename decltype(st.B)::value_type;
        for (size_t i = 0; i < n; ++i) st.B[i] = value<ValueT>(impl.reflected, i);
        if (mOptions.update == UpdateScheme::Progressive) st.unshot = st.B;
    });
    impl.narrowView(mScene);
}

size_t
RadiositySolver::cachedDirections() const
{
    return mImpl->cache ? mImpl->cache->kept() : 0;
}

size_t
RadiositySolver::cacheBytes() const
{
    return mImpl->cache ? mImpl->cache->bytes() : 0;
}

void
RadiositySolver::solve(openvdb::util::NullInterrupter* interrupt)
{
    while (!finished()) iterate(interrupt);
}

const DirectionSet&
RadiositySolver::directions() const
{
    return mImpl->schedule->directions();
}

template<typename ValueT>
void
RadiositySolver::replaceIterate(const std::vector<ValueT>& b)
{
    if (mOptions.update == UpdateScheme::Progressive) {
        OPENVDB_THROW(openvdb::ValueError, "progressive shooting carries unshot radiosity: its "
            "iterate cannot be replaced by B alone");
    }
    if (b.size() != mScene.size()) {
        OPENVDB_THROW(openvdb::ValueError, "setRadiosity: " << b.size() << " values for "
            << mScene.size() << " voxels");
    }
    Impl& impl = *mImpl;
    impl.withState(impl.rgb, [&](auto& st) {
        using StateT = std::decay_t<decltype(st)>;
        using T = typename decltype(st.B)::value_type;
        // Only the state of b's kind (grey, RGB) is ever given it (checked by the callers).
        if constexpr (StateT::kWidth * sizeof(float) == sizeof(ValueT)) {
            st.B.assign(b.size(), T());
            for (size_t i = 0; i < b.size(); ++i) {
                st.B[i] = impl.exact ? T(b[i]) - value<T>(mScene.emission(), i) : T(b[i]);
            }
        }
        if (st.mixer) st.mixer->restart();
    });
    impl.startFromSource = false;
    impl.narrowView(mScene);
    impl.gatheredStale = true;
}

void
RadiositySolver::setRadiosity(const std::vector<float>& b)
{
    if (isRgb()) OPENVDB_THROW(openvdb::ValueError, "setRadiosity: the solve is RGB");
    replaceIterate(b);
}

void
RadiositySolver::setRadiosity(const std::vector<openvdb::Vec3f>& b)
{
    if (!isRgb()) OPENVDB_THROW(openvdb::ValueError, "setRadiosity: the solve is grey");
    replaceIterate(b);
}

size_t
RadiositySolver::memoryEstimate(const Scene& scene, const RadiosityOptions& options, int threads)
{
    const bool wide = solvesInDouble(scene.albedo(), options.precision);
    const size_t channels = solvesRgb(scene, options) ? 3 : 1, scalar = wide ? 8 : 4;
    const size_t n = scene.size(), c = channels * scalar, t = size_t(std::max(threads, 1));
    size_t perVoxel = SweepSchedule::bytesPerVoxel(true, true, true);
    perVoxel += 8 + 4;                      // invZ, region
    // The sky's light per voxel, and its sums per group in the first iteration.
    if (!options.sky.empty()) perVoxel += channels * 4 + size_t(kGroups) * c;
    perVoxel += 2 * c + 4 * c;              // B, the previous B, B in each pattern's order
    if (wide) perVoxel += channels * 4;     // B rounded to float
    perVoxel += size_t(kGroups) * c;        // gathered sums per group
    perVoxel += size_t(kGroups) * scalar;   // hit weights (first iteration)
    perVoxel += t * (4 + 4 + 8 + c);        // per-thread sweep workspace: slots, facing, fronts
    const bool cache = options.visibilityCache > 0 && options.maxIterations > 1
        && options.visibility == Visibility::Sweep;
    // Per thread, a report's sweep workspace (4-byte payload), positions and code.
    if (cache) perVoxel += t * (4 + 4 + 12 + 4 + VisibilityCache::kWorstBytesPerVoxel);
    if (options.update == UpdateScheme::Progressive) perVoxel += c;
    // Exact direct light: the patch of each voxel, D, rho D and E + R in float.
    if (options.direct != DirectMode::Sweep && (scene.hasEmission() || options.sun)) {
        perVoxel += 4 + 12 + channels * 4 * 2;
    }
    if (options.accelerate == Acceleration::Anderson) {
        perVoxel += c;                      // the swept iterate
        perVoxel += wide ? AndersonMixerT<double>::bytes(channels, options.andersonDepth)
                         : AndersonMixerT<float>::bytes(channels, options.andersonDepth);
    }
    size_t bytes = n * perVoxel;
    if (scene.isGlossy()) {
        // Per glossy voxel: S, each group's splat and (first iteration) hit splat on its
        // pattern's points (at most half of them, Impl::glossySlots), the previous S, the
        // measured share, the normaliser and, with exact direct light, the direct splat; per
        // scene voxel, the glossy index in each pattern's order.
        size_t glossy = 0;
        std::vector<char> roughness(size_t(std::lround(1.0 / GlossySurfaces::kRoughnessStep)) + 1);
        for (size_t i = 0; i < n; ++i) {
            const openvdb::Vec3f ks = scene.specular().rgb(i);
            if (ks[0] > 0.f || ks[1] > 0.f || ks[2] > 0.f) {
                ++glossy;
                const long key = GlossySurfaces::roughnessKey(scene.roughness().grey(i));
                roughness[size_t(std::clamp(key, 0L, long(roughness.size()) - 1))] = 1;
            }
        }
        const bool harmonics = options.glossy.basis == GlossyBasis::Harmonics;
        const size_t P = harmonics
            ? size_t(options.glossy.harmonicOrder + 1) * size_t(options.glossy.harmonicOrder + 1)
            : size_t(options.glossy.controlPoints);
        // The groups' splats: each group holds its pattern's points (harmonics: all).
        size_t splats = size_t(kGroups) * P;
        if (!harmonics && options.directions >= 1
            && size_t(options.directions) <= DirectionSet::maxCount()) {
            const DirectionSet dirs = DirectionSet::fromCount(options.directions);
            const ControlPoints points(ControlPoints::orderForCount(int(P)));
            const LeafOrder::Patterns dealt = LeafOrder::patterns(dirs.size(),
                [&](size_t k) { return dirs.direction(k); });
            splats = 0;
            for (int g = 0; g < kGroups; ++g) {
                splats += GlossySurfaces::splatPoints(points, dirs,
                    dealt.directions[SweepSchedule::patternOf(g)]).size();
            }
        }
        bytes += glossy * (P * (2 * c + 8 + 4 + 12) + splats * (c + 8))
            + n * 4 * (SweepSchedule::kPatterns + 1);
        // One kernel per rounded roughness, and up to kMaxClasses rotations.
        const size_t lobes = size_t(std::count(roughness.begin(), roughness.end(), 1));
        const size_t classes = std::min<size_t>(GlossySurfaces::kMaxClasses, glossy);
        bytes += lobes * P * P * 4 + classes * P * 60;
        if (harmonics) {
            // Per voxel, its own normalisation where it measured a share (closed rooms: at
            // most all of them); per class, two rotations; per lobe, K in float and double.
            const size_t blocks = SphericalHarmonics::Rotation::blockOffset(
                options.glossy.harmonicOrder + 1);
            bytes += glossy * (2 * P + 3) * 8 + classes * 2 * blocks * 8 + lobes * P * P * 8;
        }
    }
    if (cache) {
        // The budget, or what every direction's report typically needs if that is less.
        size_t kept = options.visibilityCache;
        if (options.directions >= 1 && size_t(options.directions) <= DirectionSet::maxCount()) {
            const size_t dirs = DirectionSet::fromCount(options.directions).size();
            kept = std::min(kept, dirs * VisibilityCache::typicalBytes(n,
                VisibilityCache::codeFor(dirs, n, kept)));
        }
        bytes = kept > SIZE_MAX - bytes ? SIZE_MAX : bytes + kept;   // a budget may be "all"
    }
    const int slabs =
        options.spread == Spread::Slabs && options.ranks ? options.ranks->ranks() : 1;
    if (slabs > 1) {
        // One slab's share of the per-voxel arrays (no cache), each group's workspace
        // (slots, facing), one set of fronts over the whole box's lines (at most ~3 faces of
        // it) and a message in and out (a record and a ghost per line at most), and what is
        // found on the whole scene: regions and direct light.
        const openvdb::Coord d = scene.voxels().bbox().dim();
        const double face = std::max({double(d.x()) * d.y(), double(d.y()) * d.z(),
            double(d.x()) * d.z()});
        const double lines = std::min(3.0 * face, 4.0 * double(n) + 65536.0);
        bytes = bytes / size_t(slabs) + n / size_t(slabs) * size_t(kGroups) * 8
            + size_t(lines * double((8 + c) + 2 * (8 + c + 28))) + n * (4 + 12);
    }
    // Enclosure's fill: per 8^3 block of the bounding box and per leaf, up to its cap.
    if (regionBlocks(scene.voxels()) <= kEnclosureBlocks) bytes += regionsBytes(scene.voxels());
    return bytes;
}

const std::vector<float>& RadiositySolver::grey() const
{
    return mImpl->exact || mImpl->glossy ? mImpl->totalGrey : mImpl->state<float>().B;
}
const std::vector<openvdb::Vec3f>& RadiositySolver::rgb() const
{
    return mImpl->exact || mImpl->glossy ? mImpl->totalRgb : mImpl->state<openvdb::Vec3f>().B;
}
const GlossySurfaces* RadiositySolver::glossy() const { return mImpl->glossy.get(); }

openvdb::Vec3d
RadiositySolver::sent(size_t i, const openvdb::Vec3d& toward) const
{
    const Impl& impl = *mImpl;
    openvdb::Vec3d v(0.0);
    impl.withState(impl.rgb, [&](const auto& st) {
        using T = typename std::decay_t<decltype(st.B)>::value_type;
        T b = st.B[i];
        if (impl.exact) b += value<T>(mScene.emission(), i);
        if (impl.glossy && impl.glossy->glossyOf(i) != GlossySurfaces::kNone) {
            const size_t P = impl.glossy->points();
            b += impl.glossy->evaluate(&st.spec[size_t(impl.glossy->glossyOf(i)) * P], toward);
        }
        if constexpr (std::is_arithmetic_v<T>) v = openvdb::Vec3d(double(b));
        else v = openvdb::Vec3d(b[0], b[1], b[2]);
    });
    return v;
}

std::vector<openvdb::Vec3f>
RadiositySolver::specularRadiosity() const
{
    const Impl& impl = *mImpl;
    std::vector<openvdb::Vec3f> out;
    if (!impl.glossy) return out;
    out.assign(mScene.size(), openvdb::Vec3f(0.f));
    const size_t P = impl.glossy->points();
    impl.withState(impl.rgb, [&](const auto& st) {
        for (size_t k = 0; k < impl.glossy->size(); ++k) {
            const auto e = impl.glossy->exitance(k, &st.spec[k * P]);
            if constexpr (std::is_arithmetic_v<std::decay_t<decltype(e)>>) {
                out[impl.glossy->voxel(k)] = openvdb::Vec3f(float(e));
            } else {
                out[impl.glossy->voxel(k)] = openvdb::Vec3f(e);
            }
        }
    });
    return out;
}
bool RadiositySolver::exactDirect() const { return mImpl->exact; }
bool RadiositySolver::isRgb() const { return mImpl->rgb; }

bool
solvesRgb(const Scene& scene, const RadiosityOptions& options)
{
    const auto grey = [](const openvdb::Vec3d& v) { return v[0] == v[1] && v[1] == v[2]; };
    return scene.isRgb() || options.sky.isRgb() || (options.sun && !grey(options.sun->irradiance));
}
const Emitters& RadiositySolver::emitters() const { return mImpl->emitters; }
const DirectIrradiance& RadiositySolver::directLight() const { return mImpl->direct; }
bool RadiositySolver::doublePrecision() const { return mImpl->wide; }

SolveStats
RadiositySolver::stats() const
{
    SolveStats s;
    s.directions = int(directions().size());
    s.iterations = iterationCount();
    s.residual = mIteration.lastResidual();
    s.seconds = mIteration.seconds();
    s.lines = mOptions.lines == LineType::Naive ? "naive" : "standard";
    return s;
}

openvdb::GridBase::Ptr
RadiositySolver::grid() const
{
    openvdb::GridBase::Ptr grid = isRgb() ? makeRadiosityGrid(mScene, rgb(), stats())
                                                 : makeRadiosityGrid(mScene, grey(), stats());
    if (mImpl->glossy) {
        grid->insertMeta(meta::kBrdf, openvdb::StringMetadata(brdfModelName(mOptions.glossy.model)));
        if (mImpl->glossy->harmonics()) {
            grid->insertMeta(meta::kHarmonicOrder,
                openvdb::Int32Metadata(int32_t(mOptions.glossy.harmonicOrder)));
        } else {
            grid->insertMeta(meta::kControlPoints,
                openvdb::Int32Metadata(int32_t(mImpl->glossy->points())));
        }
    }
    return grid;
}

openvdb::GridBase::Ptr
RadiositySolver::specularGrid() const
{
    if (!mImpl->glossy) return nullptr;
    // Only the glossy voxels: a grid active where the lobes are.
    const std::vector<openvdb::Vec3f> s = specularRadiosity();
    const GlossySurfaces& gl = *mImpl->glossy;
    openvdb::GridBase::Ptr out;
    if (isRgb()) {
        auto g = openvdb::Vec3SGrid::create();
        auto acc = g->getAccessor();
        for (size_t k = 0; k < gl.size(); ++k) {
            acc.setValue(mScene.voxels().coord(gl.voxel(k)), s[gl.voxel(k)]);
        }
        out = g;
    } else {
        auto g = openvdb::FloatGrid::create();
        auto acc = g->getAccessor();
        for (size_t k = 0; k < gl.size(); ++k) {
            acc.setValue(mScene.voxels().coord(gl.voxel(k)), s[gl.voxel(k)][0]);
        }
        out = g;
    }
    out->setName(names::kSpecularRadiosity);
    out->setTransform(mScene.transformPtr()->copy());
    out->setGridClass(openvdb::GRID_UNKNOWN);
    out->insertMeta(meta::kBrdf, openvdb::StringMetadata(brdfModelName(mOptions.glossy.model)));
    return out;
}

std::string
RadiositySolver::describe() const
{
    std::ostringstream os;
    os << "solving " << withCommas(mImpl->slab ? mImpl->slab->frame.voxels : mScene.size())
       << " voxels";
    if (mImpl->slab) {
        os << " in " << mImpl->slab->slabs << " slabs (" << withCommas(mScene.size())
           << " on this rank)";
    }
    os << ", " << directions().size()
       << " directions (nearest to " << mOptions.directions << "), "
       << stats().lines << " lines"
       << (isRgb() ? ", RGB" : "")
       << (mOptions.accelerate == Acceleration::Anderson ? ", Anderson acceleration" : "")
       << (doublePrecision() ? ", double precision" : "");
    if (exactDirect()) {
        os << ", exact direct light (" << mOptions.directSamples << " shadow rays per voxel) from ";
        if (emitters().voxels() > 0) {
            os << withCommas(emitters().voxels()) << " emitting voxels ("
               << emitters().patches().size()
               << (emitters().patches().size() == 1 ? " patch)" : " patches)");
            if (mOptions.sun) os << " and ";
        }
        if (const auto& sun = mOptions.sun) {
            os << "the sun (zenith " << sun->zenith << ", azimuth " << sun->azimuth
               << " degrees, irradiance " << sun->irradiance << ", " << sun->diameter
               << " degrees wide)";
        }
    }
    if (!mOptions.sky.empty()) os << ", " << mOptions.sky.describe();
    if (mImpl->glossy) os << ", " << mImpl->glossy->describe();
    return os.str();
}

size_t
RadiositySolver::visibilityCacheFor(const Scene& scene, const RadiosityOptions& options,
    int threads, double available)
{
    RadiosityOptions without = options;
    without.visibilityCache = 0;
    const double rest = available - double(memoryEstimate(scene, without, threads));
    return size_t(std::min(std::max(0.5 * rest, 0.0), 1e18));
}

} // namespace vdbrad
