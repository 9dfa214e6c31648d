// RadiositySolverImpl: the surface solver's state, shared by its translation units (internal,
// not installed): RadiositySolver.cc builds and reads it, RadiositySweeps.cc iterates it,
// SolveRadiosity.cc runs whole solves.
#pragma once

#include "vdbrad/core/Precision.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/distribute/SlabDistribution.h"
#include "vdbrad/glossy/GlossySurfaces.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/sweep/Enclosure.h"
#include "vdbrad/sweep/LineSweep.h"
#include "vdbrad/sweep/RayCastVisibility.h"
#include "vdbrad/sweep/SweepSchedule.h"
#include "vdbrad/sweep/VisibilityCache.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <memory>
#include <tuple>
#include <type_traits>
#include <vector>

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
    // RadiosityOptions::sky: per direction cell (2k: +sigma, 2k + 1: -sigma) pi times its mean
    // radiance; per voxel (1 or 3 channels) the light it gathers from the sky, a constant
    // source measured by the first sweep (empty before, and without a sky).
    std::vector<openvdb::Vec3f> skyCells;
    std::vector<float> skyIn;
    bool rgb = false;                                    // the solve is RGB (solvesRgb())
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
    // Under a sky, the first iteration's splat of the sky cells their directions miss to
    // (per group), then its sum per glossy voxel and point (kept for checkpoints): a constant
    // source of their lobes, as skyIn is of the diffuse parts.
    std::vector<std::vector<openvdb::Vec3d>> glossySky;
    std::vector<openvdb::Vec3f> glossySkyIn;
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
        using Scalar = typename detail::Traits<ValueT>::Scalar;
        static constexpr size_t kWidth = sizeof(ValueT) / sizeof(Scalar);
        std::vector<ValueT> B;
        std::vector<ValueT> unshot;                          // progressive shooting only
        std::vector<std::vector<typename detail::Traits<ValueT>::Acc>> gathered;   // per group
        std::unique_ptr<AndersonMixerT<Scalar>> mixer;       // Acceleration::Anderson only
        // Glossy voxels: their lobes' reflected light S (P values per glossy voxel), and per
        // group the light splatted on its pattern's points (Impl::glossySlots) in the current
        // iteration: reflected at its end, never needed after (not checkpointed).
        std::vector<ValueT> spec;
        std::vector<std::vector<typename detail::Traits<ValueT>::Acc>> incident;
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
    void layOutGlossySlots();   // RadiositySolver.cc
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
        withState(rgb, [&](const auto& st) {
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


static_assert(RadiositySolver::kGroups == SweepSchedule::kGroups, "one group count");
static_assert(RadiositySolver::kReplayBlock == VisibilityCache::kReplayBlock, "one block size");

} // namespace vdbrad
