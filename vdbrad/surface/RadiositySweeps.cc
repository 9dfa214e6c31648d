#include "vdbrad/surface/RadiositySolverImpl.h"

#include "vdbrad/core/Constants.h"
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

// A glossy voxel's direct light (per channel; grey scenes: equal channels) as the state's type.
template<typename T> T channelsOf(const openvdb::Vec3d& v) { return T(v[0]); }
template<> openvdb::Vec3d channelsOf<openvdb::Vec3d>(const openvdb::Vec3d& v) { return v; }
// An RGB light (the sky's) as a state or accumulator type: grey solves have grey light.
template<typename T> T lightAs(const openvdb::Vec3f& v)
{
    if constexpr (std::is_arithmetic_v<T>) return T(v[0]);
    else return T(v);
}
template<typename T> double channel(const T& v, size_t c)
{
    if constexpr (std::is_arithmetic_v<T>) { (void)c; return double(v); }
    else return double(v[int(c)]);
}
} // namespace

constexpr size_t kReplayed = VisibilityCache::kReplayed;

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
        openvdb::Vec3d* sky = nullptr;   // first iteration, under a sky: what misses brings
        size_t points = 0;
        size_t slots = 0;
    };

    // How a group's sweeps treat glossy voxels: not at all (a diffuse scene), on control
    // points (three weights per direction), or on harmonics (every coefficient).
    enum GlossyKind { kDiffuse, kPoints, kHarmonics };

    // Sweep direction @a k (both senses) of a group in @a pattern, each receiver gathering what
    // it sees into G (H: the hit weights; glossy voxels: their points' splats in @a lanes).
    template<bool Hits, int Glossy>
    static void sweepDirection(RadiositySolver& s, const SweepSchedule::Pattern& pattern,
        size_t k, const std::vector<ValueT>& Bp, std::vector<AccT>& G, std::vector<Scalar>* H,
        std::vector<AccT>* S, const GlossyLanes& lanes, LineSweep::Workspace<ValueT>& work)
    {
        Impl& impl = *s.mImpl;
        const SweepSchedule& schedule = *impl.schedule;
        const openvdb::Coord& sigma = s.directions().direction(k);
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
            } else if constexpr (Hits) {
                skyMiss(impl, S, x, k, sigmaDotN, c);
                if constexpr (Glossy != kDiffuse) {
                    // A glossy voxel's lobe takes the sky's cell on the direction's points.
                    const uint32_t gx = lanes.at[x];
                    if (lanes.sky && gx != GlossySurfaces::kNone && sigmaDotN != 0.f) {
                        const openvdb::Vec3d L(impl.skyCells[2 * k + (sigmaDotN > 0.f ? 0 : 1)]);
                        const double w = double(std::abs(sigmaDotN) * c);
                        openvdb::Vec3d* I = lanes.sky + size_t(gx) * lanes.slots;
                        if constexpr (Glossy == kPoints) {
                            const ControlPoints::Weights& u = slotToward[sigmaDotN > 0.f ? 0 : 1];
                            for (int j = 0; j < 3; ++j) I[u.index[j]] += L * (w * u.weight[j]);
                        } else {
                            const float* y = harmonic[sigmaDotN > 0.f ? 0 : 1];
                            for (size_t j = 0; j < lanes.slots; ++j) I[j] += L * (w * y[j]);
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
    }

    // Group g's directions gathered into G (and their hit weights into H), from Bp (the
    // swept radiosity in g's pattern order): each direction is swept, or replayed from the
    // visibility cache, or cast (Visibility::RayCast). Glossy: senders add their lobe's light
    // along the direction, receivers splat what they see on its points (GlossySurfaces.h).
    template<bool Hits, int Glossy>
    static void gatherGroup(RadiositySolver& s, int g, const std::vector<ValueT>& Bp,
        std::vector<AccT>& G, std::vector<Scalar>* H, std::vector<AccT>* S,
        const GlossyLanes& lanes, SweepProgress& progress)
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
                if (Hits && S) {
                    const float c = impl.coefficient[k];
                    const std::vector<float>& facing = report.work.facing;
                    for (uint32_t x = 0; x < uint32_t(n); ++x) {
                        if (report.seen[x] == LineSweep::kNone) skyMiss(impl, S, x, k, facing[x], c);
                    }
                }
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
            sweepDirection<Hits, Glossy>(s, pattern, k, Bp, G, H, S, lanes, work);
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

    // x, facing the outside along direction k with nothing in sight, gathers the sky's cell
    // there (the first iteration: a constant source after it). @a S: null without a sky.
    static void skyMiss(const Impl& impl, std::vector<AccT>* S, uint32_t x, size_t k,
        float sigmaDotN, float c)
    {
        if (!S || sigmaDotN == 0.f) return;
        // x looks along +sigma (sigma . n > 0): the light comes from there.
        const openvdb::Vec3f& L = impl.skyCells[2 * k + (sigmaDotN > 0.f ? 0 : 1)];
        (*S)[x] += lightAs<AccT>(L) * (std::abs(sigmaDotN) * c);
    }

    // Spread::Slabs: the groups @a groups over this rank's slab, each direction's passes
    // chained over the ranks (SlabDistribution.h); each voxel gets gatherGroup()'s sums, in
    // the same order. Diffuse scenes only.
    template<bool Hits>
    static void slabGroups(RadiositySolver& s, const std::vector<int>& groups,
        const std::array<std::vector<ValueT>, SweepSchedule::kPatterns>& ordered,
        std::vector<std::vector<AccT>>& gathered, std::vector<std::vector<Scalar>>& hits,
        std::vector<std::vector<AccT>>& sky, SweepProgress& progress)
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
                std::vector<AccT>* S = Hits && !sky[size_t(g)].empty() ? &sky[size_t(g)] : nullptr;
                const float c = impl.coefficient[k];
                sweep.slabPass(sigma, reversed, ascending, w, fronts, in.data(), in.size(), out,
                    [&](uint32_t y) { return Bp[y]; },
                    [&](uint32_t x, const ValueT* seen, float sigmaDotN) {
                        if (seen) receive<Hits>(G, H, x, *seen, sigmaDotN, c);
                        else if (Hits) skyMiss(impl, S, x, k, sigmaDotN, c);
                    });
                if (!ascending) progress.finished(1);
            },
            [&] {
                if (progress.cancelled()) throw Cancelled("radiosity solve");
            });
    }

    // Sweep group @a g (of those this rank owns) from @a ordered, B in each pattern's order,
    // into its accumulator (and with @a measureHits its hit weights and, under a sky, its sky
    // light; glossy voxels: their points' splats).
    static void sweepGroup(RadiositySolver& s, int g,
        const std::array<std::vector<ValueT>, SweepSchedule::kPatterns>& ordered,
        std::vector<std::vector<AccT>>& gathered, std::vector<std::vector<Scalar>>& hits,
        std::vector<std::vector<AccT>>& sky, bool measureHits, SweepProgress& progress)
    {
        Impl& impl = *s.mImpl;
        Impl::State<ValueT>& st = impl.state<ValueT>();
        const GlossySurfaces* glossy = impl.glossy.get();
        const size_t n = s.mScene.size();
        std::vector<AccT>& G = gathered[size_t(g)];
        G.assign(n, openvdb::zeroVal<AccT>());
        std::vector<Scalar>* H = measureHits ? &hits[size_t(g)] : nullptr;
        const std::vector<ValueT>& Bp = ordered[SweepSchedule::patternOf(g)];
        // Compiled with and without the hit weights, so that the sweeps of every iteration but
        // the first test nothing for them, and with and without glossy voxels, so that a
        // diffuse scene's sweeps test nothing for them.
        GlossyLanes lanes;
        if (glossy) {
            const size_t slots = impl.glossySlots[SweepSchedule::patternOf(g)].size();
            std::vector<AccT>& I = st.incident[size_t(g)];
            I.assign(glossy->size() * slots, openvdb::zeroVal<AccT>());
            lanes.at = impl.glossyAt[SweepSchedule::patternOf(g)].data();
            lanes.spec = st.spec.data();
            lanes.incident = I.data();
            lanes.points = glossy->points();
            lanes.slots = slots;
            if (H) {
                impl.glossyHits[size_t(g)].assign(glossy->size() * slots, 0.0);
                lanes.hits = impl.glossyHits[size_t(g)].data();
                if (!impl.skyCells.empty()) {
                    impl.glossySky[size_t(g)].assign(glossy->size() * slots,
                        openvdb::Vec3d(0.0));
                    lanes.sky = impl.glossySky[size_t(g)].data();
                }
            }
        }
        if (H) H->assign(n, Scalar(0));
        std::vector<AccT>* S = nullptr;
        if (H && !impl.skyCells.empty()) {
            S = &sky[size_t(g)];
            S->assign(n, openvdb::zeroVal<AccT>());
        }
        auto sweepAs = [&](auto kind) {
            constexpr int kKind = decltype(kind)::value;
            if (H) gatherGroup<true, kKind>(s, g, Bp, G, H, S, lanes, progress);
            else gatherGroup<false, kKind>(s, g, Bp, G, H, S, lanes, progress);
        };
        if (!glossy) {
            sweepAs(std::integral_constant<int, kDiffuse>());
        } else if (glossy->harmonics()) {
            sweepAs(std::integral_constant<int, kHarmonics>());
        } else {
            sweepAs(std::integral_constant<int, kPoints>());
        }
    }

    // The first iteration's hit weights: closed-cavity voxels renormalised over the directions
    // that met a voxel (Enclosure.h), glossy ones' lobes likewise.
    static void applyHitWeights(RadiositySolver& s, const std::vector<std::vector<Scalar>>& hits,
        const std::vector<std::vector<AccT>>& sky)
    {
        Impl& impl = *s.mImpl;
        const SweepSchedule& schedule = *impl.schedule;
        const size_t n = s.mScene.size();
        constexpr size_t kChannels = sizeof(AccT) / sizeof(typename Traits<AccT>::Scalar);
        const bool lit = !impl.skyCells.empty();
        if (lit) impl.skyIn.assign(n * kChannels, 0.f);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n),
            [&](const tbb::blocked_range<size_t>& r) {
                for (size_t i = r.begin(); i != r.end(); ++i) {
                    double h = 0.0;
                    schedule.sum(hits, i, 1, &h);
                    if (impl.regions.region[i] == 0) {   // faces the outside: keeps its losses
                        if (lit) {
                            // What it saw of the sky, normalised as what it saw of the scene.
                            WideT light = openvdb::zeroVal<WideT>();
                            schedule.sum(sky, i, 1, &light);
                            const WideT in = light * impl.invZ[i];
                            for (size_t c = 0; c < kChannels; ++c) {
                                impl.skyIn[i * kChannels + c] = float(channel(in, c));
                            }
                        }
                        continue;
                    }
                    if (h > 0.0) impl.invZ[i] = 1.0 / h;
                }
            });
        if (const GlossySurfaces* glossy = impl.glossy.get()) {
            // Closed-room glossy voxels: their lobes normalised over the directions that met
            // something, as their diffuse part is.
            const size_t P = glossy->points();
            impl.glossyShare.assign(glossy->size() * P, 0.0);
            tbb::parallel_for(tbb::blocked_range<size_t>(0, glossy->size()),
                [&](const tbb::blocked_range<size_t>& r) {
                    for (size_t k = r.begin(); k != r.end(); ++k) {
                        if (impl.regions.region[glossy->voxel(k)] == 0) continue;
                        sumSlots(impl, impl.glossyHits, k, &impl.glossyShare[k * P]);
                    }
                });
            impl.applyGlossyShares();
            impl.glossyHits.clear();
            if (!impl.glossySky.empty()) {
                // The sky on the lobes, summed over the groups in their order.
                impl.glossySkyIn.assign(glossy->size() * P, openvdb::Vec3f(0.f));
                tbb::parallel_for(tbb::blocked_range<size_t>(0, glossy->size()),
                    [&](const tbb::blocked_range<size_t>& r) {
                        std::vector<openvdb::Vec3d> I(P);
                        for (size_t k = r.begin(); k != r.end(); ++k) {
                            std::fill(I.begin(), I.end(), openvdb::Vec3d(0.0));
                            sumSlots(impl, impl.glossySky, k, I.data());
                            for (size_t o = 0; o < P; ++o) {
                                impl.glossySkyIn[k * P + o] = openvdb::Vec3f(I[o]);
                            }
                        }
                    });
                impl.glossySky.clear();
            }
        }
        impl.hitsKnown = true;
    }

    // Each glossy voxel reflects what its points received (in group order), once per
    // iteration: a reflection costs ~support^2 products, a sweep phase a few per direction,
    // and updating the lobes after the first half too cost more than the half-iteration they
    // gain (docs/journal/2026-12-05-glossy-surfaces.md).
    static void reflectGlossy(RadiositySolver& s)
    {
        Impl& impl = *s.mImpl;
        Impl::State<ValueT>& st = impl.state<ValueT>();
        const GlossySurfaces* glossy = impl.glossy.get();
        const size_t P = glossy->points();
        tbb::parallel_for(tbb::blocked_range<size_t>(0, glossy->size()),
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
                    if (!impl.glossySkyIn.empty()) {
                        for (size_t o = 0; o < P; ++o) {
                            I[o] += channelsOf<WideT>(openvdb::Vec3d(impl.glossySkyIn[k * P + o]));
                        }
                    }
                    // Reflected in the state's own precision (the sums above are wide): float
                    // products are half the memory traffic.
                    for (size_t o = 0; o < P; ++o) In[o] = ValueT(I[o]);
                    glossy->reflect(k, In.data(), &st.spec[k * P]);
                }
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
        // ... and, under a sky, the light of the directions that meet nothing.
        std::vector<std::vector<AccT>> sky(static_cast<size_t>(kGroups));
        const bool lit = measureHits && !impl.skyCells.empty();
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
        const std::vector<ValueT> previousSpec = st.spec;
        if (glossy) {
            st.incident.resize(size_t(kGroups));
            if (measureHits) impl.glossyHits.assign(size_t(kGroups), {});
            if (measureHits && lit) impl.glossySky.assign(size_t(kGroups), {});
        }

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
            if (slabs) {
                std::vector<int> groups;
                for (int g = 0; g < kGroups; ++g) {
                    if (!inPhase(g) || schedule.patternOfGroup(g).empty()) continue;
                    groups.push_back(g);
                    gathered[size_t(g)].assign(n, openvdb::zeroVal<AccT>());
                    if (measureHits) hits[size_t(g)].assign(n, Scalar(0));
                    if (lit) sky[size_t(g)].assign(n, openvdb::zeroVal<AccT>());
                }
                if (measureHits) {
                    slabGroups<true>(s, groups, ordered, gathered, hits, sky, progress);
                } else {
                    slabGroups<false>(s, groups, ordered, gathered, hits, sky, progress);
                }
            } else {
                schedule.round(progress, "radiosity solve", ranks, inPhase,
                    [&](int g) {
                        sweepGroup(s, g, ordered, gathered, hits, sky, measureHits, progress);
                    },
                    [&](int g, int owner) {
                        ranks.share(gathered[size_t(g)], n, owner);
                        if (measureHits) ranks.share(hits[size_t(g)], n, owner);
                        if (lit) ranks.share(sky[size_t(g)], n, owner);
                        if (glossy) {
                            const size_t count = glossy->size()
                                * impl.glossySlots[SweepSchedule::patternOf(g)].size();
                            ranks.share(st.incident[size_t(g)], count, owner);
                            if (measureHits) {
                                ranks.share(impl.glossyHits[size_t(g)], count, owner);
                                if (lit) ranks.share(impl.glossySky[size_t(g)], count, owner);
                            }
                        }
                    });
            }
            if (measureHits) applyHitWeights(s, hits, sky);
            // The sky, a constant source once its shares are known: shot once when shooting.
            const bool skyLit = !impl.skyIn.empty() && (!shooting || measureHits);
            constexpr size_t kChannels = sizeof(ValueT) / sizeof(Scalar);
            tbb::parallel_for(tbb::blocked_range<size_t>(0, n),
                [&](const tbb::blocked_range<size_t>& r) {
                    for (size_t i = r.begin(); i != r.end(); ++i) {
                        WideT sum = openvdb::zeroVal<WideT>();
                        schedule.sum(gathered, i, 1, &sum);
                        ValueT incoming = ValueT(sum * impl.invZ[i]);
                        if (skyLit) {
                            const float* L = &impl.skyIn[i * kChannels];
                            if constexpr (kChannels == 1) incoming += ValueT(L[0]);
                            else incoming += ValueT(L[0], L[1], L[2]);
                        }
                        if (shooting) {
                            U[i] = value<ValueT>(scene.albedo(), i) * incoming;
                            B[i] += U[i];
                        } else {
                            B[i] = value<ValueT>(*impl.source, i)
                                + value<ValueT>(scene.albedo(), i) * incoming;
                        }
                    }
                });
            if (glossy && phase == phases - 1) reflectGlossy(s);
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

double
RadiositySolver::iterate(openvdb::util::NullInterrupter* interrupt)
{
    return mIteration.iterate([&] {
        prepareDirect(interrupt);
        double residual = 0.0;
        mImpl->withState(mImpl->rgb, [&](auto& st) {
            using ValueT = typename decltype(st.B)::value_type;
            residual = Engine<ValueT>::step(*this, interrupt);
        });
        return residual;
    });
}


} // namespace vdbrad
