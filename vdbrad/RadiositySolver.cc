#include "vdbrad/RadiositySolver.h"

#include "vdbrad/Denormals.h"
#include "vdbrad/Enclosure.h"
#include "vdbrad/Errors.h"
#include "vdbrad/LeafOrder.h"
#include "vdbrad/LineSweep.h"
#include "vdbrad/Precision.h"
#include "vdbrad/RayCastVisibility.h"
#include "vdbrad/SweepSchedule.h"
#include "vdbrad/TextFormat.h"
#include "vdbrad/VisibilityCache.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <sstream>
#include <tuple>
#include <type_traits>

namespace vdbrad {

// Closed rooms are found on the 8^3 blocks of the scene's bounding box (Enclosure.h): 4 bytes per
// block, up to 2^29 blocks (2 GiB, a box of 2^38 cells, ~6,500^3), plus ~180 bytes per leaf,
// counted in memoryEstimate(). A furnace box of 10^7 surface voxels (res 1300) spans 4.5e6 blocks
// and 1.6e5 leaves: 44 MiB, 0.8 s. Larger boxes keep their digitisation losses.
constexpr uint64_t kEnclosureBlocks = uint64_t(1) << 29;

namespace {
using namespace detail;   // Precision.h: the state types
} // namespace

// What the solver needs that does not depend on the value type.
struct RadiositySolver::Impl
{
    std::unique_ptr<SweepSchedule> schedule;
    std::unique_ptr<RayCastVisibility> rays;             // Visibility::RayCast only
    // RadiosityOptions::visibilityCache (null: none): the kept reports, in each direction's
    // pattern order; per direction, whether its report was offered to it; and each thread's
    // scratch memory for making a report.
    std::unique_ptr<VisibilityCache> cache;
    std::vector<char> offered;
    struct Report
    {
        LineSweep::Workspace<uint32_t> work;
        std::vector<uint32_t> seen;
        std::vector<uint8_t> code;
    };
    SweepSchedule::PerThread<Report> reports;
    std::vector<float> coefficient;                      // per direction: A / |s|
    std::vector<double> invZ;                            // per voxel: 1 / Z(n)
    Regions regions;                                     // per voxel: the air region it faces
    bool hitsKnown = false;                              // invZ renormalised for closed voxels
    bool gatheredStale = false;                          // B was replaced: next step is Jacobi
    bool wide = false;                                   // the state is double (Precision)
    // Exact direct light (DirectLight.h): the iterate is then R = B - E and its source is
    // rho D instead of E; `total` holds E + R in float for grey(), rgb() and grid().
    // D is computed by the first iterate(), so that a bad checkpoint or an interrupt is met
    // before the shadow rays; until then R is 0 (B = E), and it starts at rho D unless a
    // checkpoint or setRadiosity() gave it a value.
    Emitters emitters;
    bool exact = false;
    bool directReady = false;
    bool startFromSource = false;
    DirectIrradiance direct;
    Attribute reflected;                                 // rho D
    const Attribute* source = nullptr;                   // E, or rho D
    std::vector<float> totalGrey;
    std::vector<openvdb::Vec3f> totalRgb;

    // The iterate and what the next iteration needs of the last one, in one of the four types.
    template<typename ValueT>
    struct State
    {
        using Scalar = typename Traits<ValueT>::Scalar;
        static constexpr size_t kWidth = sizeof(ValueT) / sizeof(Scalar);
        std::vector<ValueT> B;
        std::vector<ValueT> unshot;                          // progressive shooting only
        std::vector<std::vector<typename Traits<ValueT>::Acc>> gathered;   // per group
        std::unique_ptr<AndersonMixerT<Scalar>> mixer;       // Acceleration::Anderson only
        SweepSchedule::PerThread<LineSweep::Workspace<ValueT>> work;
    };
    // Only the one of the scene's kind and precision is used; in double, the float one of the
    // same kind holds B rounded to float after every change, for grey(), rgb() and grid().
    std::tuple<State<float>, State<openvdb::Vec3f>, State<double>, State<openvdb::Vec3d>> states;
    template<typename ValueT> State<ValueT>& state() { return std::get<State<ValueT>>(states); }
    template<typename ValueT> const State<ValueT>& state() const
    {
        return std::get<State<ValueT>>(states);
    }
    // f(state) for the state in use.
    template<typename F> void withState(bool rgb, F&& f) { visit(*this, rgb, f); }
    template<typename F> void withState(bool rgb, F&& f) const { visit(*this, rgb, f); }
    template<typename Self, typename F> static void visit(Self& self, bool rgb, F& f)
    {
        if (self.wide) {
            if (rgb) f(self.template state<openvdb::Vec3d>());
            else f(self.template state<double>());
        } else {
            if (rgb) f(self.template state<openvdb::Vec3f>());
            else f(self.template state<float>());
        }
    }
    // After a change of B: its float rounding (double state) and, with exact direct light,
    // E + R.
    void narrowView(const Attribute& emission)
    {
        if (wide) {
            auto copy = [](auto& to, const auto& from) {
                using T = typename std::decay_t<decltype(to)>::value_type;
                to.resize(from.size());
                for (size_t i = 0; i < from.size(); ++i) to[i] = T(from[i]);
            };
            copy(state<float>().B, state<double>().B);
            copy(state<openvdb::Vec3f>().B, state<openvdb::Vec3d>().B);
        }
        if (!exact) return;
        const std::vector<float>& g = state<float>().B;
        const std::vector<openvdb::Vec3f>& c = state<openvdb::Vec3f>().B;
        totalGrey.resize(g.size());
        for (size_t i = 0; i < g.size(); ++i) totalGrey[i] = emission.grey(i) + g[i];
        totalRgb.resize(c.size());
        for (size_t i = 0; i < c.size(); ++i) totalRgb[i] = emission.rgb(i) + c[i];
    }
};

constexpr size_t kReplayed = VisibilityCache::kReplayed;
static_assert(RadiositySolver::kGroups == SweepSchedule::kGroups, "one group count");
static_assert(RadiositySolver::kReplayBlock == VisibilityCache::kReplayBlock, "one block size");

template<typename ValueT>
struct RadiositySolver::Engine
{
    using AccT = typename Traits<ValueT>::Acc;
    using WideT = typename Traits<ValueT>::Wide;
    using Scalar = typename Traits<ValueT>::Scalar;

    // One iteration, then the Anderson step when accelerated.
    static double step(RadiositySolver& s, openvdb::util::NullInterrupter* interrupt)
    {
        Impl& impl = *s.mImpl;
        Impl::State<ValueT>& st = impl.state<ValueT>();
        static_assert(sizeof(ValueT) == Impl::State<ValueT>::kWidth * sizeof(Scalar),
            "the state is mixed as scalars");
        Scalar* state = reinterpret_cast<Scalar*>(st.B.data());
        // The first sweep measures the hit weights and so changes the map: mixing starts after it.
        const bool mix = st.mixer && impl.hitsKnown;
        std::vector<Scalar> x;
        if (mix) x.assign(state, state + st.mixer->size());
        const double residual = iterate(s, st.B, interrupt);
        if (mix) {
            // Radiosity is never negative: a mixed iterate that is has overshot.
            const size_t size = st.mixer->size();
            andersonStep(*st.mixer, x.data(), state, [size](const Scalar* v) {
                return std::none_of(v, v + size, [](Scalar e) { return e < 0; });
            });
        }
        impl.narrowView(s.mScene.emission());
        return residual;
    }

    // Replay kept or raw reports of @a count directions @a ks into G (and H).
    template<bool Hits, typename ReaderT>
    static void replayed(const RadiositySolver& s, const LineSweep& sweep, const size_t* ks,
        ReaderT* readers, size_t count, const std::vector<ValueT>& Bp, std::vector<AccT>& G,
        std::vector<Scalar>* H)
    {
        std::array<float, kReplayed> c;
        std::array<openvdb::Coord, kReplayed> sigma;
        for (size_t j = 0; j < count; ++j) {
            c[j] = s.mImpl->coefficient[ks[j]];
            sigma[j] = s.directions().direction(ks[j]);
        }
        replay<Hits>(sweep, sigma.data(), c.data(), readers, count, Bp.data(), G.data(),
            Hits ? H->data() : static_cast<Scalar*>(nullptr), uint32_t(G.size()));
    }

    // Group g's directions gathered into G (and their hit weights into H), from Bp (the
    // swept radiosity in g's pattern order): each direction is swept, or replayed from the
    // visibility cache, or cast (Visibility::RayCast).
    template<bool Hits>
    static void gatherGroup(RadiositySolver& s, int g, const std::vector<ValueT>& Bp,
        std::vector<AccT>& G, std::vector<Scalar>* H, SweepProgress& progress)
    {
        Impl& impl = *s.mImpl;
        const SweepSchedule& schedule = *impl.schedule;
        const SweepSchedule::Pattern& pattern = schedule.patternOfGroup(g);
        const size_t n = G.size();
        LineSweep::Workspace<ValueT>& work = impl.state<ValueT>().work.local();
        // Kept directions wait here to be replayed together, in order.
        std::array<size_t, kReplayed> queued;
        size_t count = 0;
        auto flush = [&] {
            if (count == 0) return;
            std::array<VisibilityCache::Reader, kReplayed> readers;
            for (size_t j = 0; j < count; ++j) {
                readers[j] = VisibilityCache::Reader(*impl.cache, queued[j]);
            }
            replayed<Hits>(s, *pattern.sweep, queued.data(), readers.data(), count, Bp, G, H);
            progress.finished(count);
            count = 0;
        };
        std::vector<size_t> mine;
        schedule.forDirections(g, [&](size_t k) { mine.push_back(k); });
        for (const size_t k : mine) {
            if (progress.cancelled()) return;
            const openvdb::Coord& sigma = s.directions().direction(k);
            if (impl.cache && !impl.offered[k]) {
                // Swept once for its report, then replayed from the cache like later
                // iterations, or from the report if the cache has no room: gathering inside
                // the recording sweep read B at random between its line fronts.
                Impl::Report& report = impl.reports.local();
                report.seen.resize(n);
                pattern.sweep->seen(sigma, schedule.reversed(k), report.work, report.seen.data());
                impl.cache->offer(k, report.seen.data(), report.code);
                impl.offered[k] = 1;
                if (!impl.cache->has(k)) {
                    flush();
                    RawReport raw{report.seen.data()};
                    replayed<Hits>(s, *pattern.sweep, &k, &raw, 1, Bp, G, H);
                    progress.finished(1);
                    continue;
                }
            }
            if (impl.cache && impl.cache->has(k)) {
                queued[count++] = k;
                if (count == kReplayed) flush();
                continue;
            }
            flush();
            const float c = impl.coefficient[k];
            // x (a position in the pattern's order) receives what it sees.
            auto gather = [&](uint32_t x, const ValueT* seen, float sigmaDotN) {
                if (seen) {
                    const float w = std::abs(sigmaDotN) * c;
                    G[x] += *seen * w;
                    if constexpr (Hits) (*H)[x] += w;
                }
            };
            if (impl.rays) {
                const std::vector<uint32_t>& at = pattern.position;
                impl.rays->cast(sigma, [&](uint32_t x, uint32_t y, float dn) {
                    gather(at[x], y == RayCastVisibility::kNone ? nullptr : &Bp[at[y]], dn);
                });
            } else {
                pattern.sweep->sweep(sigma, schedule.reversed(k), work,
                    [&](uint32_t y) { return Bp[y]; }, gather);
            }
            progress.finished(1);
        }
        flush();
    }

    static double iterate(RadiositySolver& s, std::vector<ValueT>& B,
        openvdb::util::NullInterrupter* interrupt)
    {
        const Scene& scene = s.mScene;
        Impl& impl = *s.mImpl;
        const SweepSchedule& schedule = *impl.schedule;
        const size_t n = scene.size();
        // Per group, its directions' gathered sum; kept between iterations for in-place updates.
        std::vector<std::vector<AccT>>& gathered = impl.state<ValueT>().gathered;
        gathered.resize(size_t(kGroups));
        // The first iteration also measures, per voxel, the weight of the directions that meet
        // a voxel: closed-cavity voxels are renormalised over those (Enclosure.h). It is always
        // a plain Jacobi step, so that every group has a sum before in-place updates use them.
        const bool measureHits = !impl.hitsKnown;
        const bool inPlace = s.mOptions.update == UpdateScheme::InPlace
            && s.mOptions.accelerate == Acceleration::None;
        // After setRadiosity() the kept sums belong to another B: one full Jacobi step first.
        const int phases = (measureHits || !inPlace || impl.gatheredStale) ? 1 : 2;
        impl.gatheredStale = false;
        // Progressive shooting: the sweeps carry the unshot radiosity U, whose gathered light
        // is both added to B and the next U.
        const bool shooting = s.mOptions.update == UpdateScheme::Progressive;
        std::vector<ValueT>& U = impl.state<ValueT>().unshot;
        const std::vector<ValueT>& source = shooting ? U : B;
        std::vector<std::vector<Scalar>> hits(static_cast<size_t>(kGroups));
        SweepProgress progress(interrupt, s.directions().size());
        const std::vector<ValueT> previous = B;

        for (int phase = 0; phase < phases; ++phase) {
            // In two phases (in-place), groups 0-3 then 4-7 sweep, B being updated in between.
            auto inPhase = [&](int g) {
                return phases == 1 || g / SweepSchedule::kPatterns == phase;
            };
            // B in each pattern's order, so that the sweeps read it sequentially.
            std::array<std::vector<ValueT>, SweepSchedule::kPatterns> ordered;
            for (size_t p = 0; p < ordered.size(); ++p) {
                if (!schedule.pattern(p).empty()) schedule.toPatternOrder(p, source, ordered[p]);
            }
            schedule.forEachGroup(progress, "radiosity solve", inPhase, [&](int g) {
                std::vector<AccT>& G = gathered[size_t(g)];
                G.assign(n, openvdb::zeroVal<AccT>());
                std::vector<Scalar>* H = measureHits ? &hits[size_t(g)] : nullptr;
                const std::vector<ValueT>& Bp = ordered[SweepSchedule::patternOf(g)];
                // Compiled with and without the hit weights, so that the sweeps of every
                // iteration but the first test nothing for them.
                if (H) {
                    H->assign(n, Scalar(0));
                    gatherGroup<true>(s, g, Bp, G, H, progress);
                } else {
                    gatherGroup<false>(s, g, Bp, G, H, progress);
                }
            });

            if (measureHits) {
                tbb::parallel_for(tbb::blocked_range<size_t>(0, n),
                    [&](const tbb::blocked_range<size_t>& r) {
                        for (size_t i = r.begin(); i != r.end(); ++i) {
                            if (impl.regions.region[i] == 0) continue;   // faces the outside
                            double h = 0.0;
                            schedule.sum(hits, i, 1, &h);
                            if (h > 0.0) impl.invZ[i] = 1.0 / h;
                        }
                    });
                impl.hitsKnown = true;
            }
            tbb::parallel_for(tbb::blocked_range<size_t>(0, n),
                [&](const tbb::blocked_range<size_t>& r) {
                    for (size_t i = r.begin(); i != r.end(); ++i) {
                        WideT sum = openvdb::zeroVal<WideT>();
                        schedule.sum(gathered, i, 1, &sum);
                        const ValueT incoming = ValueT(sum * impl.invZ[i]);
                        if (shooting) {
                            U[i] = value<ValueT>(scene.albedo(), i) * incoming;
                            B[i] += U[i];
                        } else {
                            B[i] = value<ValueT>(*impl.source, i)
                                + value<ValueT>(scene.albedo(), i) * incoming;
                        }
                    }
                });
        }

        // Relative to the radiosity B, also where the iterate is its reflected part R = B - E.
        double maxChange = 0.0, maxSize = 0.0;
        for (size_t i = 0; i < n; ++i) {
            maxChange = std::max(maxChange, magnitudeOfDiff(B[i], previous[i]));
            maxSize = std::max(maxSize, magnitude(impl.exact
                ? ValueT(B[i] + value<ValueT>(scene.emission(), i)) : B[i]));
        }
        return maxSize > 0.0 ? maxChange / maxSize : 0.0;
    }
};

RadiositySolver::RadiositySolver(const Scene& scene, const RadiosityOptions& options)
    : IterativeSolver(FixedPointIteration(options.maxIterations, options.tolerance,
          options.accelerate, options.andersonDepth))
    , mScene(scene)
    , mOptions(options)
    , mImpl(new Impl)
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
    DirectionSet directions = DirectionSet::fromCount(options.directions);
    const size_t dirs = directions.size(), n = scene.size();

    Impl& impl = *mImpl;
    // A cache pays from the second iteration on.
    if (options.visibilityCache > 0 && options.visibility == Visibility::Sweep
        && options.maxIterations > 1) {
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
    impl.regions = findRegions(scene.voxels(), scene.normals(), options.lines, kEnclosureBlocks);
    const std::vector<uint32_t>* regions = impl.regions.cavities > 0 ? &impl.regions.region
                                                                      : nullptr;
    SweepSchedule::Layout layout;
    layout.sweeps = options.visibility == Visibility::Sweep;
    layout.lines = options.lines;
    layout.normals = &scene.normals();
    layout.depth = options.occlusionDepth;
    layout.regions = regions;
    impl.schedule.reset(new SweepSchedule(scene.voxels(), std::move(directions), layout));
    if (options.visibility == Visibility::RayCast) {
        impl.rays.reset(new RayCastVisibility(scene.voxels(), scene.normals(), options.lines,
            options.occlusionDepth, regions));
    }

    // Exact direct light: the sweeps solve R = rho (D + gathered R) for R = B - E.
    impl.source = &scene.emission();
    impl.exact = usesExactDirect(options.direct, scene);
    if (impl.exact) {
        impl.emitters = Emitters(scene);
        impl.source = &impl.reflected;   // 0 until the first iterate() computes D
        impl.startFromSource = true;
    }

    impl.wide = solvesInDouble(scene.albedo(), options.precision);
    impl.withState(scene.isRgb(), [&](auto& st) {
        using StateT = std::decay_t<decltype(st)>;
        using ValueT = typename decltype(st.B)::value_type;
        st.B.resize(n);
        for (size_t i = 0; i < n; ++i) st.B[i] = value<ValueT>(*impl.source, i);
        st.mixer = mIteration.makeMixer<typename StateT::Scalar>(n * StateT::kWidth);
        // Nothing has been shot yet: all of the source (E, or rho D) is unshot.
        if (options.update == UpdateScheme::Progressive) st.unshot = st.B;
    });
    impl.narrowView(scene.emission());
}

RadiositySolver::~RadiositySolver() = default;

double
RadiositySolver::iterate(openvdb::util::NullInterrupter* interrupt)
{
    return mIteration.iterate([&] {
        prepareDirect(interrupt);
        double residual = 0.0;
        mImpl->withState(mScene.isRgb(), [&](auto& st) {
            using ValueT = typename decltype(st.B)::value_type;
            residual = Engine<ValueT>::step(*this, interrupt);
        });
        return residual;
    });
}

void
RadiositySolver::prepareDirect(openvdb::util::NullInterrupter* interrupt)
{
    Impl& impl = *mImpl;
    if (!impl.exact || impl.directReady) return;
    const size_t n = mScene.size();
    DirectLightOptions d;
    d.samples = mOptions.directSamples;
    impl.direct = directIrradiance(mScene, impl.emitters, d,
        impl.regions.cavities > 0 ? &impl.regions.region : nullptr, interrupt);
    const std::vector<openvdb::Vec3f>& D = impl.direct.irradiance;
    if (mScene.isRgb()) {
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
    impl.withState(mScene.isRgb(), [&](auto& st) {
        using ValueT = typename decltype(st.B)::value_type;
        for (size_t i = 0; i < n; ++i) st.B[i] = value<ValueT>(impl.reflected, i);
        if (mOptions.update == UpdateScheme::Progressive) st.unshot = st.B;
    });
    impl.narrowView(mScene.emission());
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
    impl.withState(mScene.isRgb(), [&](auto& st) {
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
    impl.narrowView(mScene.emission());
    impl.gatheredStale = true;
}

void
RadiositySolver::setRadiosity(const std::vector<float>& b)
{
    if (mScene.isRgb()) OPENVDB_THROW(openvdb::ValueError, "setRadiosity: the scene is RGB");
    replaceIterate(b);
}

void
RadiositySolver::setRadiosity(const std::vector<openvdb::Vec3f>& b)
{
    if (!mScene.isRgb()) OPENVDB_THROW(openvdb::ValueError, "setRadiosity: the scene is grey");
    replaceIterate(b);
}

size_t
RadiositySolver::memoryEstimate(const Scene& scene, const RadiosityOptions& options, int threads)
{
    const bool wide = solvesInDouble(scene.albedo(), options.precision);
    const size_t channels = scene.isRgb() ? 3 : 1, scalar = wide ? 8 : 4;
    const size_t n = scene.size(), c = channels * scalar, t = size_t(std::max(threads, 1));
    size_t perVoxel = SweepSchedule::bytesPerVoxel(true, true, true);
    perVoxel += 8 + 4;                      // invZ, region
    perVoxel += 2 * c + 4 * c;              // B, the previous B, B in each pattern's order
    if (wide) perVoxel += channels * 4;     // B rounded to float
    perVoxel += size_t(kGroups) * c;        // gathered sums per group
    perVoxel += size_t(kGroups) * scalar;   // hit weights (first iteration)
    perVoxel += t * (4 + 4 + 8 + c);        // per-thread sweep workspace: slots, facing, fronts
    const bool cache = options.visibilityCache > 0 && options.maxIterations > 1
        && options.visibility == Visibility::Sweep;
    // Per thread, a report's sweep workspace (4-byte payload), positions and code.
    if (cache) perVoxel += t * (4 + 4 + 12 + 4 + VisibilityCache::worstBytes(1));
    if (options.update == UpdateScheme::Progressive) perVoxel += c;
    // Exact direct light: the patch of each voxel, D, rho D and E + R in float.
    if (options.direct != DirectMode::Sweep && scene.hasEmission()) {
        perVoxel += 4 + 12 + channels * 4 * 2;
    }
    if (options.accelerate == Acceleration::Anderson) {
        perVoxel += c;                      // the swept iterate
        perVoxel += wide ? AndersonMixerT<double>::bytes(channels, options.andersonDepth)
                         : AndersonMixerT<float>::bytes(channels, options.andersonDepth);
    }
    size_t bytes = n * perVoxel;
    if (cache) {
        // The budget, or what every direction's report typically needs if that is less.
        size_t kept = options.visibilityCache;
        if (options.directions >= 1 && size_t(options.directions) <= DirectionSet::maxCount()) {
            const size_t dirs = DirectionSet::fromCount(options.directions).size();
            kept = std::min(kept, dirs * VisibilityCache::typicalBytes(n));
        }
        bytes = kept > SIZE_MAX - bytes ? SIZE_MAX : bytes + kept;   // a budget may be "all"
    }
    // Enclosure's fill: per 8^3 block of the bounding box and per leaf, up to its cap.
    if (regionBlocks(scene.voxels()) <= kEnclosureBlocks) bytes += regionsBytes(scene.voxels());
    return bytes;
}

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
    impl.withState(mScene.isRgb(), [&](const auto& st) {
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
    });
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
    impl.withState(mScene.isRgb(), [&](auto& st) {
        using StateT = std::decay_t<decltype(st)>;
        using Scalar = typename StateT::Scalar;
        constexpr size_t width = StateT::kWidth;
        // Arrays of channels, empty or of n voxels.
        auto get = [&](const std::string& name, auto& v) {
            const std::vector<Scalar> f = state.get<Scalar>(name);
            if (!f.empty() && f.size() != n * width) {
                OPENVDB_THROW(openvdb::ValueError, "checkpoint's '" << name << "' has "
                    << f.size() << " values for " << n << " voxels");
            }
            v.resize(f.size() / width);
            if (!f.empty()) {
                std::memcpy(static_cast<void*>(v.data()), f.data(), f.size() * sizeof(Scalar));
            }
        };
        get("B", st.B);
        get("unshot", st.unshot);
        st.gathered.resize(size_t(kGroups));
        for (size_t g = 0; g < st.gathered.size(); ++g) {
            get("gathered" + std::to_string(g), st.gathered[g]);
        }
        if (st.B.size() != n) OPENVDB_THROW(openvdb::ValueError, "checkpoint has no B");
        impl.startFromSource = false;
        if (st.mixer) st.mixer->restore(state, "anderson.");
    });
    impl.narrowView(mScene.emission());
}

const std::vector<float>& RadiositySolver::grey() const
{
    return mImpl->exact ? mImpl->totalGrey : mImpl->state<float>().B;
}
const std::vector<openvdb::Vec3f>& RadiositySolver::rgb() const
{
    return mImpl->exact ? mImpl->totalRgb : mImpl->state<openvdb::Vec3f>().B;
}
bool RadiositySolver::exactDirect() const { return mImpl->exact; }
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
    return mScene.isRgb() ? makeRadiosityGrid(mScene, rgb(), stats())
                          : makeRadiosityGrid(mScene, grey(), stats());
}

std::string
RadiositySolver::describe() const
{
    std::ostringstream os;
    os << "solving " << withCommas(mScene.size()) << " voxels, " << directions().size()
       << " directions (nearest to " << mOptions.directions << "), "
       << stats().lines << " lines"
       << (mScene.isRgb() ? ", RGB" : "")
       << (mOptions.accelerate == Acceleration::Anderson ? ", Anderson acceleration" : "")
       << (doublePrecision() ? ", double precision" : "");
    if (exactDirect()) {
        os << ", exact direct light from " << withCommas(emitters().voxels())
           << " emitting voxels (" << emitters().patches().size()
           << (emitters().patches().size() == 1 ? " patch, " : " patches, ")
           << mOptions.directSamples << " shadow rays per voxel)";
    }
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

openvdb::GridBase::Ptr
solveRadiosity(const Scene& scene, const RadiosityOptions& options,
    openvdb::util::NullInterrupter* interrupt, const SolveControl& control)
{
    const bool framed = interrupt && !control.beforeIteration;
    if (framed) interrupt->start("solving radiosity");
    RadiositySolver solver(scene, options);
    iterateSolve(solver, control, interrupt);
    if (framed) interrupt->end();
    if (control.note && solver.exactDirect()) {
        const DirectIrradiance& d = solver.directLight();
        std::ostringstream os;
        os.precision(3);
        os << "direct light: " << withCommas(size_t(d.rays)) << " shadow rays, "
           << withCommas(size_t(d.factors)) << " form factors, " << d.seconds << " s";
        control.note(os.str());
    }
    if (control.note && solver.cachedDirections() > 0) {
        control.note("visibility cache: " + std::to_string(solver.cachedDirections()) + " of "
            + std::to_string(solver.directions().size()) + " directions kept ("
            + formatBytes(double(solver.cacheBytes())) + ")");
    }
    return solver.grid();
}

} // namespace vdbrad
