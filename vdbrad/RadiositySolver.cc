#include "vdbrad/RadiositySolver.h"

#include "vdbrad/Denormals.h"
#include "vdbrad/Enclosure.h"
#include "vdbrad/Errors.h"
#include "vdbrad/LeafOrder.h"
#include "vdbrad/LineSweep.h"
#include "vdbrad/RayCastVisibility.h"
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

// Above this albedo, Precision::Auto solves in double: the float floor (~6e-8 of B per sweep,
// amplified by 1 / (1 - rho) at the fixed point) would exceed ~1e-5 (BENCHMARKS.md, Extremes).
constexpr float kDoubleAlbedo = 0.999f;

namespace {

// The four state types: grey or RGB, float or double (Precision). Scalar is one channel; Acc is
// a group's accumulator, Wide the type the groups are added in.
//
// In float, each group sums about directions / kGroups terms per voxel: float keeps those short
// sums to ~1e-6 relative and halves the memory traffic of the sweeps' hottest write; the groups
// are added in double. In double everything is double (the hit weights too), so that a closed
// room's renormalised weights add up to 1 within ~1e-15 and 1 / (1 - rho) = 1e6 leaves 1e-9.
template<typename ValueT> struct Traits;
template<> struct Traits<float> { using Acc = float; using Wide = double; using Scalar = float; };
template<> struct Traits<openvdb::Vec3f>
{
    using Acc = openvdb::Vec3f;
    using Wide = openvdb::Vec3d;
    using Scalar = float;
};
template<> struct Traits<double> { using Acc = double; using Wide = double; using Scalar = double; };
template<> struct Traits<openvdb::Vec3d>
{
    using Acc = openvdb::Vec3d;
    using Wide = openvdb::Vec3d;
    using Scalar = double;
};

// Largest channel of a value, and of a difference (computed in the value's own precision).
template<typename T> double magnitude(T v) { return std::abs(double(v)); }
template<typename T> double magnitude(const openvdb::math::Vec3<T>& v)
{
    return double(std::max({v[0], v[1], v[2]}));
}
template<typename T> double magnitudeOfDiff(T a, T b) { return magnitude(a - b); }
template<typename T>
double magnitudeOfDiff(const openvdb::math::Vec3<T>& a, const openvdb::math::Vec3<T>& b)
{
    const openvdb::math::Vec3<T> d = a - b;
    return double(std::max({std::abs(d[0]), std::abs(d[1]), std::abs(d[2])}));
}
template<typename ValueT> ValueT value(const Attribute& a, size_t i);
template<> inline float value<float>(const Attribute& a, size_t i) { return a.grey(i); }
template<> inline openvdb::Vec3f value<openvdb::Vec3f>(const Attribute& a, size_t i)
{
    return a.rgb(i);
}
template<> inline double value<double>(const Attribute& a, size_t i) { return a.grey(i); }
template<> inline openvdb::Vec3d value<openvdb::Vec3d>(const Attribute& a, size_t i)
{
    return openvdb::Vec3d(a.rgb(i));
}

// Largest albedo channel of any voxel.
float
maxAlbedo(const Attribute& a)
{
    float top = a.uniformValue();
    for (float v : a.greyArray()) top = std::max(top, v);
    for (const openvdb::Vec3f& v : a.rgbArray()) top = std::max({top, v[0], v[1], v[2]});
    return top;
}

bool
solvesInDouble(const Scene& scene, const RadiosityOptions& options)
{
    switch (options.precision) {
        case Precision::Float: return false;
        case Precision::Double: return true;
        case Precision::Auto: break;
    }
    return maxAlbedo(scene.albedo()) > kDoubleAlbedo;
}

} // namespace

Precision
precisionFromString(const std::string& name)
{
    if (name == "auto") return Precision::Auto;
    if (name == "float") return Precision::Float;
    if (name == "double") return Precision::Double;
    OPENVDB_THROW(openvdb::ValueError, "unknown precision '" << name
        << "' (expected auto, float or double)");
}

const char*
toString(Precision p)
{
    switch (p) {
        case Precision::Float: return "float";
        case Precision::Double: return "double";
        case Precision::Auto: break;
    }
    return "auto";
}

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
    // After a change of a double B: its float rounding.
    void narrowView()
    {
        if (!wide) return;
        auto copy = [](auto& to, const auto& from) {
            using T = typename std::decay_t<decltype(to)>::value_type;
            to.resize(from.size());
            for (size_t i = 0; i < from.size(); ++i) to[i] = T(from[i]);
        };
        copy(state<float>().B, state<double>().B);
        copy(state<openvdb::Vec3f>().B, state<openvdb::Vec3d>().B);
    }
};

// Kept directions replayed together (a flush of the queue). Each block of kReplayBlock voxels
// takes every queued direction in turn, so that the block's group sums and normals stay in the
// first-level cache (24 KiB, RGB) while the directions' reports and seen radiosity stream by.
// Blocks of 256-4096 voxels and 8-128 directions per flush all replayed within ~10% of each
// other on the Cornell box (BENCHMARKS.md); 32 keeps progress and cancellation prompt.
constexpr size_t kReplayed = 32;
static_assert(VisibilityCache::kNone == LineSweep::kNone, "reports are LineSweep::seen()'s");

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
        impl.narrowView();
        return residual;
    }

    // A report that the cache did not keep, read entry by entry as VisibilityCache::Reader
    // reads a kept one.
    struct RawReader
    {
        const uint32_t* at;
        bool next(uint32_t& y)
        {
            y = *at++;
            return y != LineSweep::kNone;
        }
    };

    // Replay the reports of @a count directions @a ks, in order, read by @a readers: G[x] (and
    // H[x]) receive the same terms in the same order as from one sweep per direction, so the
    // same bits. In blocks of voxels, the block's G (12 bytes per voxel, RGB) and normals (12
    // more) come from memory once for all @a count directions, not once per direction against
    // ~1.2 bytes of report; what is left is decoding and the scattered reads of Bp[y].
    template<bool Hits, typename ReaderT>
    static void replay(const RadiositySolver& s, const LineSweep& sweep, const size_t* ks,
        ReaderT* readers, size_t count, const std::vector<ValueT>& Bp, std::vector<AccT>& G,
        std::vector<Scalar>* H)
    {
        const Impl& impl = *s.mImpl;
        std::array<float, kReplayed> c;
        std::array<openvdb::Coord, kReplayed> sigma;
        for (size_t j = 0; j < count; ++j) {
            c[j] = impl.coefficient[ks[j]];
            sigma[j] = s.directions().direction(ks[j]);
        }
        const uint32_t n = uint32_t(G.size());
        // Raw pointers and a block of sigma . n computed in vector lanes, so that the gather
        // loop reloads nothing it could keep in registers (through the vectors, it did: the
        // compiler could not prove the sums' stores leave them alone).
        const ValueT* bp = Bp.data();
        AccT* g = G.data();
        Scalar* h = Hits ? H->data() : nullptr;
        std::array<float, kReplayBlock> facing;
        for (uint32_t x0 = 0, x1; x0 < n; x0 = x1) {
            x1 = x0 + std::min(kReplayBlock, n - x0);
            for (size_t j = 0; j < count; ++j) {
                sweep.facing(sigma[j], x0, x1, facing.data());
                const float cj = c[j];
                ReaderT reader = readers[j];   // in registers across the block
                for (uint32_t x = x0; x < x1; ++x) {
                    uint32_t y;
                    if (!reader.next(y)) continue;
                    const float w = std::abs(facing[x - x0]) * cj;
                    g[x] += bp[y] * w;
                    if constexpr (Hits) h[x] += w;
                }
                readers[j] = reader;
            }
        }
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
            replay<Hits>(s, *pattern.sweep, queued.data(), readers.data(), count, Bp, G, H);
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
                    RawReader raw{report.seen.data()};
                    replay<Hits>(s, *pattern.sweep, &k, &raw, 1, Bp, G, H);
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
            auto inPhase = [&](int g) { return phases == 1 || g / SweepSchedule::kPatterns == phase; };
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
                            B[i] = value<ValueT>(scene.emission(), i)
                                + value<ValueT>(scene.albedo(), i) * incoming;
                        }
                    }
                });
        }

        double maxChange = 0.0, maxSize = 0.0;
        for (size_t i = 0; i < n; ++i) {
            maxChange = std::max(maxChange, magnitudeOfDiff(B[i], previous[i]));
            maxSize = std::max(maxSize, magnitude(B[i]));
        }
        return maxSize > 0.0 ? maxChange / maxSize : 0.0;
    }
};

RadiositySolver::RadiositySolver(const Scene& scene, const RadiosityOptions& options)
    : mScene(scene)
    , mOptions(options)
    , mIteration(options.maxIterations, options.tolerance, options.accelerate,
          options.andersonDepth)
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
    impl.invZ.resize(n);
    // Z costs one pass over the directions per voxel; walls of explicit scenes repeat a few
    // normals many times, so each range remembers the last few it computed.
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        std::array<std::pair<openvdb::Vec3f, double>, 8> recent;
        size_t filled = 0, next = 0;
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const openvdb::Vec3f& nrm = scene.normal(i);
            double inv = 0.0;
            bool found = false;
            for (size_t k = 0; k < filled && !found; ++k) {
                if (recent[k].first == nrm) { inv = recent[k].second; found = true; }
            }
            if (!found) {
                inv = 1.0 / directions.hemisphereSum(openvdb::Vec3d(nrm));
                recent[next] = {nrm, inv};
                next = (next + 1) % recent.size();
                filled = std::min(filled + 1, recent.size());
            }
            impl.invZ[i] = inv;
        }
    });
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

    impl.wide = solvesInDouble(scene, options);
    impl.withState(scene.isRgb(), [&](auto& st) {
        using StateT = std::decay_t<decltype(st)>;
        using ValueT = typename decltype(st.B)::value_type;
        st.B.resize(n);
        for (size_t i = 0; i < n; ++i) st.B[i] = value<ValueT>(scene.emission(), i);
        st.mixer = mIteration.makeMixer<typename StateT::Scalar>(n * StateT::kWidth);
        // Nothing has been shot yet: all of E is unshot.
        if (options.update == UpdateScheme::Progressive) st.unshot = st.B;
    });
    impl.narrowView();
}

RadiositySolver::~RadiositySolver() = default;

double
RadiositySolver::iterate(openvdb::util::NullInterrupter* interrupt)
{
    return mIteration.iterate([&] {
        double residual = 0.0;
        mImpl->withState(mScene.isRgb(), [&](auto& st) {
            using ValueT = typename decltype(st.B)::value_type;
            residual = Engine<ValueT>::step(*this, interrupt);
        });
        return residual;
    });
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
            for (size_t i = 0; i < b.size(); ++i) st.B[i] = T(b[i]);
        }
        if (st.mixer) st.mixer->restart();
    });
    impl.narrowView();
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

namespace {

uint64_t
hashAttribute(const Attribute& a, uint64_t h)
{
    const int64_t kind[1] = {int64_t(a.storage())};
    const float uniform = a.uniformValue();
    h = hashBytes(kind, sizeof kind, h);
    h = hashBytes(&uniform, sizeof uniform, h);
    h = hashBytes(a.greyArray().data(), a.greyArray().size() * sizeof(float), h);
    return hashBytes(a.rgbArray().data(), a.rgbArray().size() * sizeof(openvdb::Vec3f), h);
}

} // namespace

size_t
RadiositySolver::memoryEstimate(const Scene& scene, const RadiosityOptions& options, int threads)
{
    const bool wide = solvesInDouble(scene, options);
    const size_t channels = scene.isRgb() ? 3 : 1, scalar = wide ? 8 : 4;
    const size_t n = scene.size(), c = channels * scalar, t = size_t(std::max(threads, 1));
    // Four visiting-order layouts: order and position (u32 each), the sweep's coordinates,
    // normals and regions in that order.
    size_t perVoxel = 4 * (4 + 4 + 12 + 12 + 4);
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
    h = hashAttribute(mScene.albedo(), h);
    h = hashAttribute(mScene.emission(), h);
    const int64_t options[8] = {mOptions.directions, int64_t(mOptions.lines),
        int64_t(mOptions.update), int64_t(mOptions.visibility), int64_t(mOptions.accelerate),
        mOptions.andersonDepth, int64_t(directions().size()), int64_t(mImpl->wide)};
    h = hashBytes(options, sizeof options, h);
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
        if (st.mixer) st.mixer->restore(state, "anderson.");
    });
    impl.narrowView();
}

const std::vector<float>& RadiositySolver::grey() const
{
    return mImpl->state<float>().B;
}
const std::vector<openvdb::Vec3f>& RadiositySolver::rgb() const
{
    return mImpl->state<openvdb::Vec3f>().B;
}
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
       << (mOptions.lines == LineType::Naive ? "naive" : "standard") << " lines"
       << (mScene.isRgb() ? ", RGB" : "")
       << (mOptions.accelerate == Acceleration::Anderson ? ", Anderson acceleration" : "")
       << (doublePrecision() ? ", double precision" : "");
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
    RadiositySolver solver(scene, options);
    const bool framed = interrupt && !control.beforeIteration;
    if (framed) interrupt->start("solving radiosity");
    iterateSolve(solver, control, interrupt);
    if (framed) interrupt->end();
    if (control.note && solver.cachedDirections() > 0) {
        control.note("visibility cache: " + std::to_string(solver.cachedDirections()) + " of "
            + std::to_string(solver.directions().size()) + " directions kept ("
            + formatBytes(double(solver.cacheBytes())) + ")");
    }
    return solver.grid();
}

} // namespace vdbrad
