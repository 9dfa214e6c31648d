#include "vdbrad/RadiositySolver.h"

#include "vdbrad/Enclosure.h"
#include "vdbrad/Errors.h"
#include "vdbrad/LeafOrder.h"
#include "vdbrad/LineSweep.h"
#include "vdbrad/RayCastVisibility.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>

namespace vdbrad {

namespace {

// Each group sums about directions / kGroups terms per voxel: float keeps those short sums to
// ~1e-6 relative and halves the memory traffic of the sweeps' hottest write; the groups are added
// in double.
template<typename ValueT> struct Accumulator;
template<> struct Accumulator<float> { using Type = float; using Wide = double; };
template<> struct Accumulator<openvdb::Vec3f>
{
    using Type = openvdb::Vec3f;
    using Wide = openvdb::Vec3d;
};

inline float magnitude(float v) { return std::abs(v); }
inline float magnitude(const openvdb::Vec3f& v) { return std::max({v[0], v[1], v[2]}); }
inline float magnitudeOfDiff(float a, float b) { return std::abs(a - b); }
inline float magnitudeOfDiff(const openvdb::Vec3f& a, const openvdb::Vec3f& b)
{
    const openvdb::Vec3f d = a - b;
    return std::max({std::abs(d[0]), std::abs(d[1]), std::abs(d[2])});
}
template<typename ValueT> ValueT value(const Attribute& a, size_t i);
template<> inline float value<float>(const Attribute& a, size_t i) { return a.grey(i); }
template<> inline openvdb::Vec3f value<openvdb::Vec3f>(const Attribute& a, size_t i)
{
    return a.rgb(i);
}
inline float narrow(double v) { return float(v); }
inline openvdb::Vec3f narrow(const openvdb::Vec3d& v) { return openvdb::Vec3f(v); }
inline double widen(float v) { return double(v); }
inline openvdb::Vec3d widen(const openvdb::Vec3f& v) { return openvdb::Vec3d(v); }

} // namespace

// What the solver needs that does not depend on the value type.
struct RadiositySolver::Impl
{
    // The voxels laid out in the visiting order of one base sign pattern (LeafOrder), with the
    // directions that pattern serves. Accumulator group g works in pattern g % 4's order.
    struct Pattern
    {
        std::vector<uint32_t> order;        // position -> voxel
        std::vector<uint32_t> position;     // voxel -> position
        std::unique_ptr<LineSweep> sweep;
        std::vector<size_t> directions;
    };
    std::array<Pattern, 4> patterns;
    std::unique_ptr<RayCastVisibility> rays;             // Visibility::RayCast only
    std::vector<char> reversed;                          // per direction
    std::vector<float> coefficient;                      // per direction: A / |s|
    std::vector<float> invZ;                             // per voxel: 1 / Z(n)
    Regions regions;                                     // per voxel: the air region it faces
    bool hitsKnown = false;                              // invZ renormalised for closed voxels
    std::vector<float> grey;
    std::vector<openvdb::Vec3f> rgb;
    std::vector<float> greyUnshot;                       // progressive shooting only
    std::vector<openvdb::Vec3f> rgbUnshot;
    std::vector<std::vector<float>> greyGathered;           // per group, kept between iterations
    std::vector<std::vector<openvdb::Vec3f>> rgbGathered;

    static int patternOf(int group) { return group % 4; }
    // The directions of group g: every other one of its pattern's.
    template<typename F> void forDirections(int group, F&& f) const
    {
        const std::vector<size_t>& dirs = patterns[size_t(patternOf(group))].directions;
        for (size_t j = size_t(group / 4); j < dirs.size(); j += kGroups / 4) f(dirs[j]);
    }
};

template<typename ValueT>
struct RadiositySolver::Engine
{
    using AccT = typename Accumulator<ValueT>::Type;
    using WideT = typename Accumulator<ValueT>::Wide;

    static std::vector<std::vector<AccT>>& accumulators(Impl& impl);
    static std::vector<ValueT>& unshot(Impl& impl);

    static double iterate(RadiositySolver& s, std::vector<ValueT>& B,
        openvdb::util::NullInterrupter* interrupt)
    {
        static_assert(kGroups % 4 == 0, "groups are dealt to the 4 sign patterns");
        const Scene& scene = s.mScene;
        Impl& impl = *s.mImpl;
        const size_t n = scene.size();
        const size_t dirs = s.mDirections.size();
        // Per group, its directions' gathered sum; kept between iterations for in-place updates.
        std::vector<std::vector<AccT>>& gathered = accumulators(impl);
        gathered.resize(size_t(kGroups));
        // The first iteration also measures, per voxel, the weight of the directions that meet
        // a voxel: closed-cavity voxels are renormalised over those (Enclosure.h). It is always
        // a plain Jacobi step, so that every group has a sum before in-place updates use them.
        const bool measureHits = !impl.hitsKnown;
        const bool inPlace = s.mOptions.update == UpdateScheme::InPlace;
        const int phases = (measureHits || !inPlace) ? 1 : 2;
        // Progressive shooting: the sweeps carry the unshot radiosity U, whose gathered light
        // is both added to B and the next U.
        const bool shooting = s.mOptions.update == UpdateScheme::Progressive;
        std::vector<ValueT>& U = unshot(impl);
        const std::vector<ValueT>& source = shooting ? U : B;
        std::vector<std::vector<float>> hits(static_cast<size_t>(kGroups));
        std::atomic<size_t> done{0};
        std::atomic<bool> cancelled{false};
        const std::vector<ValueT> previous = B;

        // Group g's arrays are in pattern g % 4's order: read voxel i at its position there.
        auto sumGroups = [&](auto& arrays, size_t i, auto zero) {
            auto sum = zero;
            for (int g = 0; g < kGroups; ++g) {
                const auto& a = arrays[size_t(g)];
                if (!a.empty()) sum += widen(a[impl.patterns[size_t(Impl::patternOf(g))].position[i]]);
            }
            return sum;
        };

        for (int phase = 0; phase < phases; ++phase) {
            // In two phases (in-place), groups 0-3 then 4-7 sweep, B being updated in between.
            auto inPhase = [&](int g) { return phases == 1 || g / 4 == phase; };
            // B in each pattern's order, so that the sweeps read it sequentially.
            std::array<std::vector<ValueT>, 4> ordered;
            for (size_t p = 0; p < 4; ++p) {
                const Impl::Pattern& pattern = impl.patterns[p];
                if (pattern.directions.empty()) continue;
                ordered[p].resize(n);
                tbb::parallel_for(tbb::blocked_range<size_t>(0, n),
                    [&](const tbb::blocked_range<size_t>& r) {
                        for (size_t k = r.begin(); k != r.end(); ++k) {
                            ordered[p][k] = source[pattern.order[k]];
                        }
                    });
            }
            tbb::parallel_for(tbb::blocked_range<int>(0, kGroups, 1),
                [&](const tbb::blocked_range<int>& r) {
                    for (int g = r.begin(); g != r.end(); ++g) {
                        const size_t p = size_t(Impl::patternOf(g));
                        if (!inPhase(g) || impl.patterns[p].directions.empty()) continue;
                        const Impl::Pattern& pattern = impl.patterns[p];
                        const std::vector<ValueT>& Bp = ordered[p];
                        std::vector<AccT>& G = gathered[size_t(g)];
                        G.assign(n, openvdb::zeroVal<AccT>());
                        std::vector<float>* H = measureHits ? &hits[size_t(g)] : nullptr;
                        if (H) H->assign(n, 0.f);
                        LineSweep::Workspace<ValueT> work;
                        impl.forDirections(g, [&](size_t k) {
                            if (cancelled.load(std::memory_order_relaxed)) return;
                            const float c = impl.coefficient[k];
                            // x (a position in the pattern's order) receives what it sees.
                            auto gather = [&](uint32_t x, const ValueT* seen, float sigmaDotN) {
                                if (seen) {
                                    const float w = std::abs(sigmaDotN) * c;
                                    G[x] += *seen * w;
                                    if (H) (*H)[x] += w;
                                }
                            };
                            const openvdb::Coord& sigma = s.mDirections.direction(k);
                            if (impl.rays) {
                                const std::vector<uint32_t>& at = pattern.position;
                                impl.rays->cast(sigma, [&](uint32_t x, uint32_t y, float dn) {
                                    gather(at[x], y == RayCastVisibility::kNone ? nullptr
                                        : &Bp[at[y]], dn);
                                });
                            } else {
                                pattern.sweep->sweep(sigma, impl.reversed[k] != 0, work,
                                    [&](uint32_t y) { return Bp[y]; }, gather);
                            }
                            const size_t d = ++done;
                            if (interrupt && interrupt->wasInterrupted(int(100 * d / dirs))) {
                                cancelled = true;
                            }
                        });
                    }
                });
            if (cancelled) throw Cancelled("radiosity solve");

            if (measureHits) {
                tbb::parallel_for(tbb::blocked_range<size_t>(0, n),
                    [&](const tbb::blocked_range<size_t>& r) {
                        for (size_t i = r.begin(); i != r.end(); ++i) {
                            if (impl.regions.region[i] == 0) continue;   // faces the outside
                            const double h = sumGroups(hits, i, 0.0);
                            if (h > 0.0) impl.invZ[i] = float(1.0 / h);
                        }
                    });
                impl.hitsKnown = true;
            }
            tbb::parallel_for(tbb::blocked_range<size_t>(0, n),
                [&](const tbb::blocked_range<size_t>& r) {
                    for (size_t i = r.begin(); i != r.end(); ++i) {
                        const WideT sum = sumGroups(gathered, i, openvdb::zeroVal<WideT>());
                        const ValueT incoming = narrow(sum * double(impl.invZ[i]));
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

        float maxChange = 0.f, maxSize = 0.f;
        for (size_t i = 0; i < n; ++i) {
            maxChange = std::max(maxChange, magnitudeOfDiff(B[i], previous[i]));
            maxSize = std::max(maxSize, magnitude(B[i]));
        }
        return maxSize > 0.f ? double(maxChange) / double(maxSize) : 0.0;
    }
};

template<>
std::vector<std::vector<float>>&
RadiositySolver::Engine<float>::accumulators(Impl& impl)
{
    return impl.greyGathered;
}

template<>
std::vector<std::vector<openvdb::Vec3f>>&
RadiositySolver::Engine<openvdb::Vec3f>::accumulators(Impl& impl)
{
    return impl.rgbGathered;
}

template<>
std::vector<float>&
RadiositySolver::Engine<float>::unshot(Impl& impl)
{
    return impl.greyUnshot;
}

template<>
std::vector<openvdb::Vec3f>&
RadiositySolver::Engine<openvdb::Vec3f>::unshot(Impl& impl)
{
    return impl.rgbUnshot;
}

RadiositySolver::RadiositySolver(const Scene& scene, const RadiosityOptions& options)
    : mScene(scene)
    , mOptions(options)
    , mImpl(new Impl)
{
    if (options.directions < 1) {
        OPENVDB_THROW(openvdb::ValueError, "directions must be >= 1, got " << options.directions);
    }
    if (options.maxIterations < 1) {
        OPENVDB_THROW(openvdb::ValueError, "iterations must be >= 1, got "
            << options.maxIterations);
    }
    if (!(options.tolerance >= 0.0)) {
        OPENVDB_THROW(openvdb::ValueError, "tolerance must be >= 0, got " << options.tolerance);
    }
    if (!(options.occlusionDepth > 0.f)) {
        OPENVDB_THROW(openvdb::ValueError, "occlusion depth must be > 0, got "
            << options.occlusionDepth);
    }
    mDirections = DirectionSet::fromCount(options.directions);
    const size_t dirs = mDirections.size(), n = scene.size();

    Impl& impl = *mImpl;
    LeafOrder::Patterns dealt = LeafOrder::patterns(dirs,
        [&](size_t k) { return mDirections.direction(k); });
    impl.reversed = std::move(dealt.reversed);
    for (size_t p = 0; p < 4; ++p) impl.patterns[p].directions = std::move(dealt.directions[p]);
    const std::array<LeafOrder::Signs, 4>& signsOf = dealt.signs;
    impl.coefficient.resize(dirs);
    for (size_t k = 0; k < dirs; ++k) {
        const openvdb::Coord& d = mDirections.direction(k);
        impl.coefficient[k] = float(mDirections.factor(k) / openvdb::Vec3d(d.asVec3d()).length());
    }
    // Per-voxel normalisation of the direction factors (DirectionSet.h).
    impl.invZ.resize(n);
    // Z costs one pass over the directions per voxel; walls of explicit scenes repeat a few
    // normals many times, so each range remembers the last few it computed.
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        std::array<std::pair<openvdb::Vec3f, float>, 8> recent;
        size_t filled = 0, next = 0;
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const openvdb::Vec3f& nrm = scene.normal(i);
            float inv = 0.f;
            bool found = false;
            for (size_t k = 0; k < filled && !found; ++k) {
                if (recent[k].first == nrm) { inv = recent[k].second; found = true; }
            }
            if (!found) {
                inv = float(1.0 / mDirections.hemisphereSum(openvdb::Vec3d(nrm)));
                recent[next] = {nrm, inv};
                next = (next + 1) % recent.size();
                filled = std::min(filled + 1, recent.size());
            }
            impl.invZ[i] = inv;
        }
    });
    impl.regions = findRegions(scene.voxels(), scene.normals(), options.lines);
    for (size_t p = 0; p < 4; ++p) {
        Impl::Pattern& pattern = impl.patterns[p];
        if (pattern.directions.empty()) continue;
        const LeafOrder order(scene.voxels(), signsOf[p]);
        pattern.order = order.voxels();
        pattern.position.resize(n);
        for (size_t k = 0; k < n; ++k) pattern.position[pattern.order[k]] = uint32_t(k);
        if (options.visibility == Visibility::Sweep) {
            pattern.sweep.reset(new LineSweep(scene.voxels(), order, &scene.normals(),
                options.lines, options.occlusionDepth,
                impl.regions.cavities > 0 ? &impl.regions.region : nullptr));
        }
    }
    if (options.visibility == Visibility::RayCast) {
        impl.rays.reset(new RayCastVisibility(scene.voxels(), scene.normals(), options.lines,
            options.occlusionDepth, impl.regions.cavities > 0 ? &impl.regions.region : nullptr));
    }

    if (scene.isRgb()) {
        impl.rgb.resize(n);
        for (size_t i = 0; i < n; ++i) impl.rgb[i] = scene.emission().rgb(i);
    } else {
        impl.grey.resize(n);
        for (size_t i = 0; i < n; ++i) impl.grey[i] = scene.emission().grey(i);
    }
    // Nothing has been shot yet: all of E is unshot.
    if (options.update == UpdateScheme::Progressive) {
        impl.greyUnshot = impl.grey;
        impl.rgbUnshot = impl.rgb;
    }
}

RadiositySolver::~RadiositySolver() = default;

double
RadiositySolver::iterate(openvdb::util::NullInterrupter* interrupt)
{
    const auto t0 = std::chrono::steady_clock::now();
    const double residual = mScene.isRgb()
        ? Engine<openvdb::Vec3f>::iterate(*this, mImpl->rgb, interrupt)
        : Engine<float>::iterate(*this, mImpl->grey, interrupt);
    mSeconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    mResiduals.push_back(residual);
    return residual;
}

bool
RadiositySolver::converged() const
{
    return !mResiduals.empty() && mResiduals.back() <= mOptions.tolerance;
}

void
RadiositySolver::solve(openvdb::util::NullInterrupter* interrupt)
{
    while (!converged() && iterationCount() < mOptions.maxIterations) iterate(interrupt);
}

const std::vector<float>& RadiositySolver::grey() const { return mImpl->grey; }
const std::vector<openvdb::Vec3f>& RadiositySolver::rgb() const { return mImpl->rgb; }

SolveStats
RadiositySolver::stats() const
{
    SolveStats s;
    s.directions = int(mDirections.size());
    s.iterations = iterationCount();
    s.residual = mResiduals.empty() ? 0.0 : mResiduals.back();
    s.seconds = mSeconds;
    s.lines = mOptions.lines == LineType::Naive ? "naive" : "standard";
    return s;
}

openvdb::GridBase::Ptr
RadiositySolver::grid() const
{
    return mScene.isRgb() ? makeRadiosityGrid(mScene, mImpl->rgb, stats())
                          : makeRadiosityGrid(mScene, mImpl->grey, stats());
}

openvdb::GridBase::Ptr
solveRadiosity(const Scene& scene, const RadiosityOptions& options,
    openvdb::util::NullInterrupter* interrupt)
{
    RadiositySolver solver(scene, options);
    if (interrupt) interrupt->start("solving radiosity");
    solver.solve(interrupt);
    if (interrupt) interrupt->end();
    return solver.grid();
}

} // namespace vdbrad
