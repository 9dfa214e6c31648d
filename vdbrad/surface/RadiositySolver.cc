#include "vdbrad/surface/RadiositySolver.h"
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

// Closed rooms are found on the 8^3 blocks of the scene's bounding box (Enclosure.h): 4 bytes per
// block, up to 2^29 blocks (2 GiB, a box of 2^38 cells, ~6,500^3), plus ~180 bytes per leaf,
// counted in memoryEstimate(). A furnace box of 10^7 surface voxels (res 1300) spans 4.5e6 blocks
// and 1.6e5 leaves: 44 MiB, 0.8 s. Larger boxes keep their digitisation losses.
constexpr uint64_t kEnclosureBlocks = uint64_t(1) << 29;

// What a slab's solver takes from the whole scene: the frame its lines are keyed in, and what
// only the whole scene can tell (air regions, direct light, the exact-direct and precision
// choices, which a slab alone could make differently from its neighbours).
struct RadiositySolver::SlabContext
{
    LineSweep::Frame frame;
    Regions regions;               // the slab's voxels' regions
    bool exact = false;
    bool wide = false;
    Emitters emitters;             // exact direct light: the whole scene's
    DirectIrradiance direct;       // ... and the slab's voxels' irradiance
    int slabs = 1;
};

namespace {
using namespace detail;   // Precision.h: the state types

// A glossy voxel's direct light (per channel; grey scenes: equal channels) as the state's type.
template<typename T> T channelsOf(const openvdb::Vec3d& v) { return T(v[0]); }
template<> openvdb::Vec3d channelsOf<openvdb::Vec3d>(const openvdb::Vec3d& v) { return v; }
} // namespace

// What the solver needs that does not depend on the value type.
struct RadiositySolver::Impl
{
    // The ranks of RadiosityOptions::ranks, or this process alone where it gives none.
    Distribution alone;
    const Distribution& ranksFor(const RadiosityOptions& o) const
    {
        return Distribution::orAlone(o.ranks, alone);
    }
    std::unique_ptr<SweepSchedule> schedule;
    std::unique_ptr<RayCastVisibility> rays;             // Visibility::RayCast only
    // Spread::Slabs under mpirun (null otherwise): the whole scene's part, and the chain of
    // ranks the line fronts go along.
    std::shared_ptr<const SlabContext> slab;
    std::unique_ptr<SlabPipeline> pipeline;
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
    // Glossy voxels (GlossySurfaces.h; null for a diffuse scene, which allocates none of
    // this): per pattern, each position's glossy index; the first iteration's splatted hit
    // weights per group and the measured shares (kept for checkpoints); with exact direct
    // light, each glossy voxel's direct light splatted on the points (per channel).
    std::unique_ptr<GlossySurfaces> glossy;
    std::array<std::vector<uint32_t>, SweepSchedule::kPatterns> glossyAt;
    std::vector<std::vector<double>> glossyHits;
    std::vector<double> glossyShare;
    std::vector<openvdb::Vec3f> glossyDirect;
    // A pattern's directions (both senses) splat on a few of the points only (two opposite
    // octants and their borders: 66 of 162): per pattern, those points, and per direction,
    // its two interpolations numbered in its pattern's list. A group's splats hold only these.
    std::array<std::vector<uint32_t>, SweepSchedule::kPatterns> glossySlots;
    std::vector<ControlPoints::Weights> glossySlotToward;

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
        // Glossy voxels: their lobes' reflected light S (P values per glossy voxel), and per
        // group the light splatted on its pattern's points (Impl::glossySlots) in the current
        // iteration: reflected at its end, never needed after (not checkpointed).
        std::vector<ValueT> spec;
        std::vector<std::vector<typename Traits<ValueT>::Acc>> incident;
        SweepSchedule::PerThread<LineSweep::Workspace<ValueT>> work;
        // Slabs: each group's (its direction's two passes are apart in time), and one set of
        // fronts for all (the passes run one at a time, and each leaves them empty: a set per
        // group over the whole box's lines would be most of a rank's memory).
        std::array<LineSweep::Workspace<ValueT>, SweepSchedule::kGroups> slabWork;
        std::vector<LineSweep::Front<ValueT>> slabFronts;
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
    // The lobes' normalisation from the measured shares (empty ones: the full hemisphere).
    void applyGlossyShares()
    {
        const size_t P = glossy->points();
        tbb::parallel_for(tbb::blocked_range<size_t>(0, glossy->size()),
            [&](const tbb::blocked_range<size_t>& r) {
                for (size_t k = r.begin(); k != r.end(); ++k) {
                    const double* share = glossyShare.empty() ? nullptr : &glossyShare[k * P];
                    const bool any = share && std::any_of(share, share + P,
                        [](double h) { return h > 0.0; });
                    glossy->setShare(k, any ? share : nullptr);
                }
            });
    }

    // After a change of B: its float rounding (double state) and, with exact direct light or
    // glossy voxels, the radiosity E + R or B_d + the lobes' exitance.
    void narrowView(const Scene& scene)
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
        if (!exact && !glossy) return;
        const Attribute& emission = scene.emission();
        const std::vector<float>& g = state<float>().B;
        const std::vector<openvdb::Vec3f>& c = state<openvdb::Vec3f>().B;
        totalGrey.resize(g.size());
        for (size_t i = 0; i < g.size(); ++i) totalGrey[i] = (exact ? emission.grey(i) : 0.f) + g[i];
        totalRgb.resize(c.size());
        for (size_t i = 0; i < c.size(); ++i) {
            totalRgb[i] = (exact ? emission.rgb(i) : openvdb::Vec3f(0.f)) + c[i];
        }
        if (!glossy) return;
        const size_t P = glossy->points();
        withState(scene.isRgb(), [&](const auto& st) {
            using T = typename std::decay_t<decltype(st.B)>::value_type;
            if (st.spec.empty()) return;
            for (size_t k = 0; k < glossy->size(); ++k) {
                const T e = glossy->exitance(k, &st.spec[k * P]);
                const size_t i = glossy->voxel(k);
                if constexpr (std::is_arithmetic_v<T>) totalGrey[i] += float(e);
                else totalRgb[i] += openvdb::Vec3f(e);
            }
        });
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
        impl.narrowView(s.mScene);
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

    // out[0, P) += glossy voxel k's splats in every group (its pattern's points), in group
    // order.
    template<typename ArraysT, typename OutT>
    static void sumSlots(const Impl& impl, const ArraysT& groups, size_t k, OutT* out)
    {
        for (size_t g = 0; g < groups.size(); ++g) {
            const auto& a = groups[g];
            if (a.empty()) continue;
            const std::vector<uint32_t>& slots = impl.glossySlots[SweepSchedule::patternOf(int(g))];
            const size_t w = slots.size();
            for (size_t j = 0; j < w; ++j) out[slots[j]] += OutT(a[k * w + j]);
        }
    }

    // What a group's sweeps read and write for glossy voxels: their glossy indices (in the
    // group's pattern order), their lobes' light S (P points each), and the group's splat of
    // what they receive (and, in the first iteration, of the weights of the directions that
    // meet something), `slots` values each (the pattern's points).
    struct GlossyLanes
    {
        const uint32_t* at = nullptr;
        const ValueT* spec = nullptr;
        AccT* incident = nullptr;
        double* hits = nullptr;
        size_t points = 0;
        size_t slots = 0;
    };

    // Group g's directions gathered into G (and their hit weights into H), from Bp (the
    // swept radiosity in g's pattern order): each direction is swept, or replayed from the
    // visibility cache, or cast (Visibility::RayCast). Glossy: senders add their lobe's light
    // along the direction, receivers splat what they see on its points (GlossySurfaces.h).
    // How a group's sweeps treat glossy voxels: not at all (a diffuse scene), on control
    // points (three weights per direction), or on harmonics (every coefficient).
    enum GlossyKind { kDiffuse, kPoints, kHarmonics };
    template<bool Hits, int Glossy>
    static void gatherGroup(RadiositySolver& s, int g, const std::vector<ValueT>& Bp,
        std::vector<AccT>& G, std::vector<Scalar>* H, const GlossyLanes& lanes,
        SweepProgress& progress)
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
            auto replayAs = [&](auto reader) {
                using ReaderT = decltype(reader);
                std::array<ReaderT, kReplayed> readers;
                for (size_t j = 0; j < count; ++j) readers[j] = ReaderT(*impl.cache, queued[j]);
                replayed<Hits>(s, *pattern.sweep, queued.data(), readers.data(), count, Bp, G, H);
            };
            if (impl.cache->code() == VisibilityCache::Code::Bytes) {
                replayAs(VisibilityCache::ByteReader());
            } else {
                replayAs(VisibilityCache::Reader());
            }
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
            // Glossy: the points of +sigma and -sigma (senders: of all P; receivers: in the
            // pattern's slots).
            const ControlPoints::Weights* toward[2] = {nullptr, nullptr};
            const ControlPoints::Weights* slotToward = nullptr;
            const float* harmonic[2] = {nullptr, nullptr};
            if constexpr (Glossy == kPoints) {
                toward[0] = &impl.glossy->toward(k, false);
                toward[1] = &impl.glossy->toward(k, true);
                slotToward = &impl.glossySlotToward[2 * k];
            } else if constexpr (Glossy == kHarmonics) {
                harmonic[0] = impl.glossy->harmonicToward(k, false);
                harmonic[1] = impl.glossy->harmonicToward(k, true);
            }
            // x (a position in the pattern's order) receives what it sees.
            auto gather = [&](uint32_t x, const ValueT* seen, float sigmaDotN) {
                if (seen) {
                    const float w = receive<Hits>(G, H, x, *seen, sigmaDotN, c);
                    if constexpr (Glossy == kPoints) {
                        const uint32_t gx = lanes.at[x];
                        if (gx != GlossySurfaces::kNone) {
                            // x looks along +sigma (sigma . n > 0): the light comes from there.
                            const ControlPoints::Weights& u = slotToward[sigmaDotN > 0.f ? 0 : 1];
                            AccT* I = lanes.incident + size_t(gx) * lanes.slots;
                            for (int j = 0; j < 3; ++j) {
                                I[u.index[j]] += *seen * float(w * u.weight[j]);
                            }
                            if constexpr (Hits) {
                                double* h = lanes.hits + size_t(gx) * lanes.slots;
                                for (int j = 0; j < 3; ++j) h[u.index[j]] += w * u.weight[j];
                            }
                        }
                    } else if constexpr (Glossy == kHarmonics) {
                        const uint32_t gx = lanes.at[x];
                        if (gx != GlossySurfaces::kNone) {
                            const float* y = harmonic[sigmaDotN > 0.f ? 0 : 1];
                            AccT* I = lanes.incident + size_t(gx) * lanes.slots;
                            for (size_t j = 0; j < lanes.slots; ++j) I[j] += *seen * (w * y[j]);
                            if constexpr (Hits) {
                                double* h = lanes.hits + size_t(gx) * lanes.slots;
                                for (size_t j = 0; j < lanes.slots; ++j) h[j] += w * y[j];
                            }
                        }
                    }
                }
            };
            if (impl.rays) {
                const std::vector<uint32_t>& at = pattern.position;
                impl.rays->cast(sigma, [&](uint32_t x, uint32_t y, float dn) {
                    gather(at[x], y == RayCastVisibility::kNone ? nullptr : &Bp[at[y]], dn);
                });
            } else if constexpr (Glossy != kDiffuse) {
                // A glossy sender adds its lobe's light along the sense it faces.
                pattern.sweep->sweep(sigma, schedule.reversed(k), work,
                    [&](uint32_t y) {
                        ValueT v = Bp[y];
                        const uint32_t gy = lanes.at[y];
                        if (gy != GlossySurfaces::kNone) {
                            const ValueT* S = lanes.spec + size_t(gy) * lanes.points;
                            if constexpr (Glossy == kPoints) {
                                const ControlPoints::Weights& u =
                                    *toward[work.facing[y] > 0.f ? 0 : 1];
                                for (int j = 0; j < 3; ++j) {
                                    v += S[u.index[j]] * float(u.weight[j]);
                                }
                            } else {
                                const float* h = harmonic[work.facing[y] > 0.f ? 0 : 1];
                                for (size_t j = 0; j < lanes.points; ++j) v += S[j] * h[j];
                            }
                        }
                        return v;
                    },
                    gather);
            } else {
                pattern.sweep->sweep(sigma, schedule.reversed(k), work,
                    [&](uint32_t y) { return Bp[y]; }, gather);
            }
            progress.finished(1);
        }
        flush();
    }

    // x receives @a seen along a direction of coefficient c: its weight |sigma . n| c, added
    // to its sum and (first iteration) to its hit weight. Returns the weight.
    template<bool Hits>
    static float receive(std::vector<AccT>& G, std::vector<Scalar>* H, uint32_t x,
        const ValueT& seen, float sigmaDotN, float c)
    {
        const float w = std::abs(sigmaDotN) * c;
        G[x] += seen * w;
        if constexpr (Hits) (*H)[x] += w;
        return w;
    }

    // Spread::Slabs: the groups @a groups over this rank's slab, each direction's passes
    // chained over the ranks (SlabDistribution.h); each voxel gets gatherGroup()'s sums, in
    // the same order. Diffuse scenes only.
    template<bool Hits>
    static void slabGroups(RadiositySolver& s, const std::vector<int>& groups,
        const std::array<std::vector<ValueT>, SweepSchedule::kPatterns>& ordered,
        std::vector<std::vector<AccT>>& gathered, std::vector<std::vector<Scalar>>& hits,
        SweepProgress& progress)
    {
        Impl& impl = *s.mImpl;
        const SweepSchedule& schedule = *impl.schedule;
        auto& work = impl.state<ValueT>().slabWork;
        auto& fronts = impl.state<ValueT>().slabFronts;
        std::array<std::vector<size_t>, SweepSchedule::kGroups> mine;
        std::vector<std::pair<int, size_t>> list;
        for (const int g : groups) {
            schedule.forDirections(g, [&](size_t k) { mine[size_t(g)].push_back(k); });
            list.emplace_back(g, mine[size_t(g)].size());
        }
        const ScopedFlushDenormals flush;   // as forEachGroup(): the same bits
        impl.pipeline->run(list,
            [&](int g, size_t j, bool ascending, const std::vector<char>& in,
                std::vector<char>& out) {
                const size_t k = mine[size_t(g)][j];
                const LineSweep& sweep = *schedule.patternOfGroup(g).sweep;
                LineSweep::Workspace<ValueT>& w = work[size_t(g)];
                const openvdb::Coord& sigma = s.directions().direction(k);
                const bool reversed = schedule.reversed(k);
                if (ascending) sweep.prepareSlab(sigma, reversed, w);
                const std::vector<ValueT>& Bp = ordered[SweepSchedule::patternOf(g)];
                std::vector<AccT>& G = gathered[size_t(g)];
                std::vector<Scalar>* H = Hits ? &hits[size_t(g)] : nullptr;
                const float c = impl.coefficient[k];
                sweep.slabPass(sigma, reversed, ascending, w, fronts, in.data(), in.size(), out,
                    [&](uint32_t y) { return Bp[y]; },
                    [&](uint32_t x, const ValueT* seen, float sigmaDotN) {
                        if (seen) receive<Hits>(G, H, x, *seen, sigmaDotN, c);
                    });
                if (!ascending) progress.finished(1);
            },
            [&] {
                if (progress.cancelled()) throw Cancelled("radiosity solve");
            });
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
        // Under MPI each rank sweeps its own groups (Distribution.h) and counts only theirs.
        const Distribution& ranks = impl.ranksFor(s.mOptions);
        // With slabs every rank sweeps every direction, over its slab.
        const bool slabs = impl.pipeline != nullptr;
        SweepProgress progress(interrupt,
            schedule.directionsOf([&](int g) { return slabs || ranks.owns(g); }));
        const std::vector<ValueT> previous = B;
        // Glossy voxels: per group, the light splatted on their points.
        Impl::State<ValueT>& st = impl.state<ValueT>();
        const GlossySurfaces* glossy = impl.glossy.get();
        const size_t P = glossy ? glossy->points() : 0, glossyN = glossy ? glossy->size() : 0;
        const std::vector<ValueT> previousSpec = st.spec;
        if (glossy) {
            st.incident.resize(size_t(kGroups));
            if (measureHits) impl.glossyHits.assign(size_t(kGroups), {});
        }

        for (int phase = 0; phase < phases; ++phase) {
            // In two phases (in-place), groups 0-3 then 4-7 sweep, B being updated in between.
            auto inPhase = [&](int g) {
                return phases == 1 || g / SweepSchedule::kPatterns == phase;
            };
            auto mineInPhase = [&](int g) { return inPhase(g) && ranks.owns(g); };
            // B in each pattern's order, so that the sweeps read it sequentially.
            std::array<std::vector<ValueT>, SweepSchedule::kPatterns> ordered;
            for (size_t p = 0; p < ordered.size(); ++p) {
                if (!schedule.pattern(p).empty()) schedule.toPatternOrder(p, source, ordered[p]);
            }
            if (slabs) {
                std::vector<int> groups;
                for (int g = 0; g < kGroups; ++g) {
                    if (!inPhase(g) || schedule.patternOfGroup(g).empty()) continue;
                    groups.push_back(g);
                    gathered[size_t(g)].assign(n, openvdb::zeroVal<AccT>());
                    if (measureHits) hits[size_t(g)].assign(n, Scalar(0));
                }
                if (measureHits) slabGroups<true>(s, groups, ordered, gathered, hits, progress);
                else slabGroups<false>(s, groups, ordered, gathered, hits, progress);
            } else {
                schedule.forEachGroup(progress, "radiosity solve", mineInPhase, [&](int g) {
                    std::vector<AccT>& G = gathered[size_t(g)];
                    G.assign(n, openvdb::zeroVal<AccT>());
                    std::vector<Scalar>* H = measureHits ? &hits[size_t(g)] : nullptr;
                    const std::vector<ValueT>& Bp = ordered[SweepSchedule::patternOf(g)];
                    // Compiled with and without the hit weights, so that the sweeps of every
                    // iteration but the first test nothing for them, and with and without glossy
                    // voxels, so that a diffuse scene's sweeps test nothing for them.
                    GlossyLanes lanes;
                    if (glossy) {
                        const size_t slots = impl.glossySlots[SweepSchedule::patternOf(g)].size();
                        std::vector<AccT>& I = st.incident[size_t(g)];
                        I.assign(glossyN * slots, openvdb::zeroVal<AccT>());
                        lanes.at = impl.glossyAt[SweepSchedule::patternOf(g)].data();
                        lanes.spec = st.spec.data();
                        lanes.incident = I.data();
                        lanes.points = P;
                        lanes.slots = slots;
                        if (H) {
                            impl.glossyHits[size_t(g)].assign(glossyN * slots, 0.0);
                            lanes.hits = impl.glossyHits[size_t(g)].data();
                        }
                    }
                    if (H) H->assign(n, Scalar(0));
                    auto sweepAs = [&](auto kind) {
                        constexpr int kKind = decltype(kind)::value;
                        if (H) gatherGroup<true, kKind>(s, g, Bp, G, H, lanes, progress);
                        else gatherGroup<false, kKind>(s, g, Bp, G, H, lanes, progress);
                    };
                    if (!glossy) {
                        sweepAs(std::integral_constant<int, kDiffuse>());
                    } else if (glossy->harmonics()) {
                        sweepAs(std::integral_constant<int, kHarmonics>());
                    } else {
                        sweepAs(std::integral_constant<int, kPoints>());
                    }
                });
            }
            if (ranks.distributed() && !slabs) {
                // Every rank gets every group's sums from its owner, then sums them in group
                // order as one process does: the same bits for any number of ranks.
                for (int g = 0; g < kGroups; ++g) {
                    if (!inPhase(g) || schedule.patternOfGroup(g).empty()) continue;
                    const int owner = ranks.ownerOf(g);
                    ranks.share(gathered[size_t(g)], n, owner);
                    if (measureHits) ranks.share(hits[size_t(g)], n, owner);
                    if (glossy) {
                        const size_t count = glossyN
                            * impl.glossySlots[SweepSchedule::patternOf(g)].size();
                        ranks.share(st.incident[size_t(g)], count, owner);
                        if (measureHits) ranks.share(impl.glossyHits[size_t(g)], count, owner);
                    }
                }
            }

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
                if (glossy) {
                    // Closed-room glossy voxels: their lobes normalised over the directions
                    // that met something, as their diffuse part is.
                    impl.glossyShare.assign(glossyN * P, 0.0);
                    tbb::parallel_for(tbb::blocked_range<size_t>(0, glossyN),
                        [&](const tbb::blocked_range<size_t>& r) {
                            for (size_t k = r.begin(); k != r.end(); ++k) {
                                if (impl.regions.region[glossy->voxel(k)] == 0) continue;
                                sumSlots(impl, impl.glossyHits, k, &impl.glossyShare[k * P]);
                            }
                        });
                    impl.applyGlossyShares();
                    impl.glossyHits.clear();
                }
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
            if (glossy && phase == phases - 1) {
                // Each glossy voxel reflects what its points received (in group order), once
                // per iteration: a reflection costs ~support^2 products, a sweep phase a few
                // per direction, and updating the lobes after the first half too cost more
                // (docs/journal/2026-12-05-glossy-surfaces.md) than the half-iteration they gain.
                tbb::parallel_for(tbb::blocked_range<size_t>(0, glossyN),
                    [&](const tbb::blocked_range<size_t>& r) {
                        std::vector<WideT> I(P);
                        std::vector<ValueT> In(P);
                        for (size_t k = r.begin(); k != r.end(); ++k) {
                            std::fill(I.begin(), I.end(), openvdb::zeroVal<WideT>());
                            sumSlots(impl, st.incident, k, I.data());
                            if (!impl.glossyDirect.empty()) {
                                // Irradiance to a splat: times the voxel's cosine sum 1 / invZ.
                                const double z = 1.0 / impl.invZ[glossy->voxel(k)];
                                for (size_t o = 0; o < P; ++o) {
                                    I[o] += channelsOf<WideT>(
                                        openvdb::Vec3d(impl.glossyDirect[k * P + o]) * z);
                                }
                            }
                            // Reflected in the state's own precision (the sums above are
                            // wide): float products are half the memory traffic.
                            for (size_t o = 0; o < P; ++o) In[o] = ValueT(I[o]);
                            glossy->reflect(k, In.data(), &st.spec[k * P]);
                        }
                    });
            }
        }

        // Relative to the radiosity B, also where the iterate is its reflected part R = B - E.
        double maxChange = 0.0, maxSize = 0.0;
        for (size_t i = 0; i < n; ++i) {
            maxChange = std::max(maxChange, magnitudeOfDiff(B[i], previous[i]));
            maxSize = std::max(maxSize, magnitude(impl.exact
                ? ValueT(B[i] + value<ValueT>(scene.emission(), i)) : B[i]));
        }
        for (size_t e = 0; e < st.spec.size(); ++e) {
            maxChange = std::max(maxChange, magnitudeOfDiff(st.spec[e], previousSpec[e]));
            maxSize = std::max(maxSize, magnitude(st.spec[e]));
        }
        if (slabs) {
            // Over the whole scene.
            maxChange = ranks.maximum(maxChange);
            maxSize = ranks.maximum(maxSize);
        }
        return maxSize > 0.0 ? maxChange / maxSize : 0.0;
    }
};

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
    impl.slab = std::move(slab);
    if (impl.slab) {
        // What the slab passes do not carry (SlabDistribution.h).
        auto refuse = [](const char* what) {
            OPENVDB_THROW(openvdb::ValueError, "a solve spread over slabs " << what);
        };
        if (scene.isGlossy()) refuse("needs diffuse surfaces (no `specular` grid)");
        if (options.lines != LineType::Naive) refuse("needs naive lines");
        if (options.visibility != Visibility::Sweep) refuse("needs the line sweeps");
        if (options.accelerate != Acceleration::None) refuse("is not Anderson-accelerated");
        impl.pipeline.reset(new SlabPipeline(impl.ranksFor(options)));
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
        impl.glossy.reset(new GlossySurfaces(scene, directions, options.glossy));
    }
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
    if (impl.glossy) {
        const size_t P = impl.glossy->points();
        impl.glossySlotToward.resize(2 * dirs);
        for (size_t p = 0; p < impl.glossyAt.size(); ++p) {
            const SweepSchedule::Pattern& pattern = impl.schedule->pattern(p);
            const std::vector<uint32_t>& order = pattern.order;
            if (order.empty()) continue;
            impl.glossyAt[p].resize(order.size());
            for (size_t x = 0; x < order.size(); ++x) {
                impl.glossyAt[p][x] = impl.glossy->glossyOf(order[x]);
            }
            std::vector<uint32_t>& slots = impl.glossySlots[p];
            if (impl.glossy->harmonics()) {
                // Every direction splats on every coefficient.
                slots.resize(P);
                for (size_t j = 0; j < P; ++j) slots[j] = uint32_t(j);
                continue;
            }
            slots = GlossySurfaces::splatPoints(impl.glossy->controlPoints(),
                impl.schedule->directions(), pattern.directions);
            std::vector<uint32_t> slot(P, GlossySurfaces::kNone);
            for (size_t j = 0; j < slots.size(); ++j) slot[slots[j]] = uint32_t(j);
            for (const size_t k : pattern.directions) {
                for (const bool negative : {false, true}) {
                    ControlPoints::Weights w = impl.glossy->toward(k, negative);
                    for (uint32_t& i : w.index) i = slot[i];
                    impl.glossySlotToward[2 * k + (negative ? 1 : 0)] = w;
                }
            }
        }
    }
    if (options.visibility == Visibility::RayCast) {
        impl.rays.reset(new RayCastVisibility(scene.voxels(), scene.normals(), options.lines,
            options.occlusionDepth, regions));
    }

    // Exact direct light: the sweeps solve R = rho (D + gathered R) for R = B - E.
    impl.source = &scene.emission();
    impl.exact = impl.slab ? impl.slab->exact : usesExactDirect(options.direct, scene);
    if (impl.exact) {
        impl.emitters = impl.slab ? impl.slab->emitters : Emitters(scene);
        impl.source = &impl.reflected;   // 0 until the first iterate() computes D
        impl.startFromSource = true;
    }

    impl.wide = impl.slab ? impl.slab->wide : solvesInDouble(scene.albedo(), options.precision);
    impl.withState(scene.isRgb(), [&](auto& st) {
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
    d.ranks = mOptions.ranks;
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
    impl.narrowView(mScene);
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
    if (cache) perVoxel += t * (4 + 4 + 12 + 4 + VisibilityCache::kWorstBytesPerVoxel);
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
        if (impl.glossy) {
            put("glossy.spec", st.spec);
        }
    });
    if (impl.glossy) {
        state.put("glossy.share", impl.glossyShare);
        state.put("glossy.direct", reinterpret_cast<const float*>(impl.glossyDirect.data()),
            impl.glossyDirect.size() * 3);
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
    impl.withState(mScene.isRgb(), [&](auto& st) {
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
        impl.applyGlossyShares();
    }
    impl.narrowView(mScene);
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
    impl.withState(mScene.isRgb(), [&](const auto& st) {
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
    impl.withState(mScene.isRgb(), [&](const auto& st) {
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
    openvdb::GridBase::Ptr grid = mScene.isRgb() ? makeRadiosityGrid(mScene, rgb(), stats())
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
    if (mScene.isRgb()) {
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
       << (mScene.isRgb() ? ", RGB" : "")
       << (mOptions.accelerate == Acceleration::Anderson ? ", Anderson acceleration" : "")
       << (doublePrecision() ? ", double precision" : "");
    if (exactDirect()) {
        os << ", exact direct light from " << withCommas(emitters().voxels())
           << " emitting voxels (" << emitters().patches().size()
           << (emitters().patches().size() == 1 ? " patch, " : " patches, ")
           << mOptions.directSamples << " shadow rays per voxel)";
    }
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

namespace {

// Iterate @a solver to its end (SolveControl), framed as one progress step unless the control
// reports each iteration, and note the direct light's cost.
void
runSolver(RadiositySolver& solver, openvdb::util::NullInterrupter* interrupt,
    const SolveControl& control)
{
    const bool framed = interrupt && !control.beforeIteration;
    if (framed) interrupt->start("solving radiosity");
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
}

// Spread::Slabs under mpirun: this rank solves its slab of @a scene (SlabDistribution.h),
// with the regions and the direct light found on the whole scene, and rank 0 gathers the
// slabs' radiosity into the whole scene's grid. @a owned: the scene, where the caller gave it
// up, so that the ranks other than 0 free it once their slab is set up.
openvdb::GridBase::Ptr
solveSlabs(const Scene& scene, Scene* owned, const RadiosityOptions& options,
    openvdb::util::NullInterrupter* interrupt, const SolveControl& control)
{
    const Distribution& ranks = *options.ranks;   // distributed: solveRadiosity() checked
    if (!control.checkpoint.empty() || !control.resume.empty()) {
        OPENVDB_THROW(openvdb::ValueError, "a solve spread over slabs keeps no checkpoints");
    }
    const SlabPartition partition(scene.voxels(), ranks.ranks());
    const std::vector<uint32_t> mine = partition.voxelsOf(scene.voxels(), ranks.rank());
    auto context = std::make_shared<RadiositySolver::SlabContext>();
    context->frame.box = scene.voxels().bbox();
    context->frame.voxels = scene.size();
    context->slabs = ranks.ranks();
    context->wide = solvesInDouble(scene.albedo(), options.precision);
    context->exact = usesExactDirect(options.direct, scene);
    {
        Regions whole = findRegions(scene.voxels(), scene.normals(), options.lines,
            kEnclosureBlocks);
        context->regions.cavities = whole.cavities;
        context->regions.analysed = whole.analysed;
        context->regions.region.resize(mine.size());
        for (size_t k = 0; k < mine.size(); ++k) {
            context->regions.region[k] = whole.region[mine[k]];
        }
        if (context->exact) {
            context->emitters = Emitters(scene);
            DirectLightOptions d;
            d.samples = options.directSamples;
            d.ranks = options.ranks;
            // Shared out between the ranks in blocks (Distribution.h) and combined.
            DirectIrradiance D = directIrradiance(scene, context->emitters, d,
                whole.cavities > 0 ? &whole.region : nullptr, interrupt);
            context->direct = D;
            context->direct.irradiance.resize(mine.size());
            for (size_t k = 0; k < mine.size(); ++k) {
                context->direct.irradiance[k] = D.irradiance[mine[k]];
            }
        }
    }
    const Scene slab = scene.subset(mine);
    if (owned && ranks.rank() != 0) *owned = Scene();
#ifdef __GLIBC__
    // What the set-up on the whole scene freed (many small blocks) back to the system: what a
    // rank holds while it solves is then its slab's share.
    ::malloc_trim(0);
#endif
    RadiositySolver solver(slab, options, context);
    runSolver(solver, interrupt, control);
    // What each rank holds with its slab's solver: what falls with the ranks.
    const double resident = residentBytes();
    const double most = ranks.maximum(resident), least = -ranks.maximum(-resident);

    // The slabs' radiosity, in slab order, to rank 0.
    const bool rgb = slab.isRgb();
    const void* data = rgb ? static_cast<const void*>(solver.rgb().data())
                           : static_cast<const void*>(solver.grey().data());
    const size_t width = rgb ? sizeof(openvdb::Vec3f) : sizeof(float);
    const std::vector<std::vector<char>> parts = ranks.gather(data, mine.size() * width, 0);
    if (ranks.rank() != 0) return nullptr;
    std::vector<float> grey(rgb ? 0 : scene.size());
    std::vector<openvdb::Vec3f> colour(rgb ? scene.size() : 0);
    char* whole = rgb ? reinterpret_cast<char*>(colour.data())
                      : reinterpret_cast<char*>(grey.data());
    for (int r = 0; r < ranks.ranks(); ++r) {
        const std::vector<uint32_t> voxels = partition.voxelsOf(scene.voxels(), r);
        const std::vector<char>& part = parts[size_t(r)];
        if (part.size() != voxels.size() * width) {
            OPENVDB_THROW(openvdb::RuntimeError, "rank " << r << " sent " << part.size()
                << " bytes for " << voxels.size() << " voxels");
        }
        for (size_t k = 0; k < voxels.size(); ++k) {
            std::memcpy(whole + size_t(voxels[k]) * width, part.data() + k * width, width);
        }
    }
    if (control.note) {
        std::ostringstream os;
        os.precision(3);
        os << "slabs: " << ranks.ranks() << " ranks, rank 0 held " << withCommas(mine.size())
           << " of " << withCommas(scene.size()) << " voxels";
        if (most > 0.0) {
            os << "; resident while solving: " << formatBytes(least) << " to "
               << formatBytes(most) << " per rank";
        }
        control.note(os.str());
    }
    return rgb ? makeRadiosityGrid(scene, colour, solver.stats())
               : makeRadiosityGrid(scene, grey, solver.stats());
}

} // namespace

openvdb::GridBase::Ptr
solveRadiosity(Scene&& scene, const RadiosityOptions& options,
    openvdb::util::NullInterrupter* interrupt, const SolveControl& control,
    openvdb::GridBase::Ptr* specular)
{
    if (options.spread == Spread::Slabs && options.ranks && options.ranks->distributed()) {
        if (specular) specular->reset();
        return solveSlabs(scene, &scene, options, interrupt, control);
    }
    return solveRadiosity(static_cast<const Scene&>(scene), options, interrupt, control,
        specular);
}

openvdb::GridBase::Ptr
solveRadiosity(const Scene& scene, const RadiosityOptions& options,
    openvdb::util::NullInterrupter* interrupt, const SolveControl& control,
    openvdb::GridBase::Ptr* specular)
{
    if (options.spread == Spread::Slabs && options.ranks && options.ranks->distributed()) {
        if (specular) specular->reset();
        return solveSlabs(scene, nullptr, options, interrupt, control);
    }
    RadiositySolver solver(scene, options);
    runSolver(solver, interrupt, control);
    if (control.note && solver.cachedDirections() > 0) {
        control.note("visibility cache: " + std::to_string(solver.cachedDirections()) + " of "
            + std::to_string(solver.directions().size()) + " directions kept ("
            + formatBytes(double(solver.cacheBytes())) + ")");
    }
    if (control.note && solver.glossy()) {
        std::ostringstream os;
        os.precision(3);
        os << "glossy: " << solver.glossy()->describe() << ", set up in "
           << solver.glossy()->setupSeconds() << " s";
        control.note(os.str());
    }
    if (specular) *specular = solver.specularGrid();
    return solver.grid();
}

} // namespace vdbrad
