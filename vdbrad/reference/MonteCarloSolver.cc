#include "vdbrad/reference/MonteCarloSolver.h"

#include "vdbrad/core/TextFormat.h"

#include "vdbrad/core/Errors.h"
#include "vdbrad/core/SampleHash.h"
#include "vdbrad/scene/Emitters.h"
#include "vdbrad/surface/SurfaceRays.h"
#include "vdbrad/sweep/Enclosure.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <type_traits>

namespace vdbrad {

namespace {

using Accessor = VoxelIndex::Accessor;

static_assert(MonteCarloSolver::kSky == kRaySky && MonteCarloSolver::kBack == kRayBack,
    "one ray code");

// Rays leave from just in front of the voxel's plane: the estimate is the irradiance where they
// start, so kRayLift (half a voxel) would move a floor half a voxel nearer a lamp above it (the
// disk's irradiance 2-3 standard errors high at 1024 rays); the wall's voxels share the plane,
// so a hair in front is enough for all but the most grazing rays.
constexpr double kMonteCarloLift = 0.01;

// What the ray from voxel @a self along unit @a d hits (see the header).
uint32_t
trace(const Scene& scene, const SurfacePlanes& planes, Accessor& acc,
    const openvdb::CoordBBox& box, uint32_t self, const openvdb::Vec3d& d)
{
    return traceSurface(scene, planes, acc, box, self,
        planes.rayOrigin(self, scene.voxels().coord(self).asVec3d(), kMonteCarloLift), d);
}

template<typename ValueT> ValueT value(const Attribute& a, size_t i);
template<> float value<float>(const Attribute& a, size_t i) { return a.grey(i); }
template<> openvdb::Vec3f value<openvdb::Vec3f>(const Attribute& a, size_t i) { return a.rgb(i); }

inline float component(float v, int) { return v; }
inline float component(const openvdb::Vec3f& v, int c) { return v[c]; }
inline void setComponent(float& v, int, float x) { v = x; }
inline void setComponent(openvdb::Vec3f& v, int c, float x) { v[c] = x; }

} // namespace

MonteCarloSolver::MonteCarloSolver(const Scene& scene, const MonteCarloOptions& options,
    openvdb::util::NullInterrupter* interrupt)
    : IterativeSolver(FixedPointIteration(options.maxIterations, options.tolerance,
          Acceleration::None, 1))
    , mScene(scene), mOptions(options), mPlanes(scene)
    , mEmission(Emitters(scene).exitance(scene))
{
    if (options.samples < 1) {
        OPENVDB_THROW(openvdb::ValueError, "samples must be >= 1, got " << options.samples);
    }
    if (options.gather < 0) {
        OPENVDB_THROW(openvdb::ValueError, "gather rays must be >= 0, got " << options.gather);
    }
    const size_t n = scene.size(), S = size_t(options.samples);
    mHits.resize(n * S);
    const openvdb::CoordBBox box = scene.voxels().bbox();
    std::atomic<size_t> done{0};
    std::atomic<bool> cancelled{false};
    const auto t0 = std::chrono::steady_clock::now();
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 64), [&](const tbb::blocked_range<size_t>& r) {
        if (cancelled) return;
        Accessor acc(scene.voxels().tree());
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const uint64_t h = mixHash(options.seed ^ mixHash(uint64_t(i)));
            const CosineRays rays(scene.normal(i), h, S);
            for (size_t s = 0; s < S; ++s) {
                mHits[i * S + s] = trace(scene, mPlanes, acc, box, uint32_t(i), rays(s));
            }
        }
        const size_t d = done += r.size();
        if (interrupt && interrupt->wasInterrupted(int(100 * d / std::max<size_t>(n, 1)))) {
            cancelled = true;
        }
    });
    if (cancelled) throw Cancelled("Monte Carlo rays");

    // A voxel facing a closed cavity averages over the rays that hit a voxel: a ray leaving
    // the room through the voxel's own cube (a corner patch tilted across the wall) is a
    // digitisation artefact, not sky. The line-partition solver renormalises the same way.
    const Regions regions = findRegions(scene.voxels(), scene.normals(), LineType::Naive);
    mClosed.assign(n, 0);
    for (size_t i = 0; i < n; ++i) mClosed[i] = regions.region[i] != 0 ? 1 : 0;
    mIteration.addSeconds(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());

    if (scene.isRgb()) {
        mRgb.resize(n);
        mRgbError.assign(n, openvdb::Vec3f(0.f));
        for (size_t i = 0; i < n; ++i) mRgb[i] = mEmission.rgb(i);
    } else {
        mGrey.resize(n);
        mGreyError.assign(n, 0.f);
        for (size_t i = 0; i < n; ++i) mGrey[i] = mEmission.grey(i);
    }
}

template<typename ValueT>
double
MonteCarloSolver::iterate(std::vector<ValueT>& B, std::vector<ValueT>& err)
{
    const size_t n = mScene.size(), S = size_t(mOptions.samples);
    constexpr int channels = std::is_same<ValueT, float>::value ? 1 : 3;
    std::vector<ValueT> next(n);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const ValueT e = value<ValueT>(mEmission, i);
            const ValueT rho = value<ValueT>(mScene.albedo(), i);
            ValueT out = e, sd = e;
            for (int c = 0; c < channels; ++c) {
                // Sums in double: S can be large and the values spread. The variance of the
                // mean is estimated by collapsing the u-strata in pairs (one ray per stratum):
                // (1 / S^2) sum over pairs (v_2k - v_2k+1)^2, a conservative estimate.
                double sum = 0.0, pairs = 0.0, previous = 0.0;
                size_t used = 0;
                for (size_t s = 0; s < S; ++s) {
                    const uint32_t y = mHits[i * S + s];
                    if (y == kSky && mClosed[i]) continue;
                    const double b = y < kBack ? double(component(B[y], c)) : 0.0;
                    sum += b;
                    if (used % 2 == 1) pairs += (b - previous) * (b - previous);
                    previous = b;
                    ++used;
                }
                const double mean = used > 0 ? sum / double(used) : 0.0;
                const double var = used > 1 ? pairs / double(used / 2 * 2) / double(used) : 0.0;
                const double p = component(rho, c);
                setComponent(out, c, float(component(e, c) + p * mean));
                setComponent(sd, c, float(p * std::sqrt(var)));
            }
            next[i] = out;
            err[i] = sd;
        }
    });
    double maxChange = 0.0, maxSize = 0.0;
    for (size_t i = 0; i < n; ++i) {
        for (int c = 0; c < channels; ++c) {
            maxChange = std::max(maxChange,
                std::abs(double(component(next[i], c)) - double(component(B[i], c))));
            maxSize = std::max(maxSize, std::abs(double(component(next[i], c))));
        }
    }
    B.swap(next);
    return maxSize > 0.0 ? maxChange / maxSize : 0.0;
}

double
MonteCarloSolver::iterate(openvdb::util::NullInterrupter* interrupt)
{
    if (interrupt && interrupt->wasInterrupted()) throw Cancelled("Monte Carlo solve");
    return mIteration.iterate([&] {
        return mScene.isRgb() ? iterate(mRgb, mRgbError) : iterate(mGrey, mGreyError);
    });
}

template<typename ValueT>
void
MonteCarloSolver::gather(const std::vector<ValueT>& B, const std::vector<ValueT>& storedError,
    const std::vector<size_t>& voxels, size_t perBatch, std::vector<ValueT>& value, std::vector<ValueT>& error,
    openvdb::util::NullInterrupter* interrupt) const
{
    constexpr int channels = std::is_same<ValueT, float>::value ? 1 : 3;
    constexpr int K = kGatherBatches;
    value.assign(voxels.size(), ValueT(0.f));
    error.assign(voxels.size(), ValueT(0.f));
    const openvdb::CoordBBox box = mScene.voxels().bbox();
    std::atomic<size_t> done{0};
    std::atomic<bool> cancelled{false};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, voxels.size(), 1),
        [&](const tbb::blocked_range<size_t>& r) {
        if (cancelled) return;
        Accessor acc(mScene.voxels().tree());
        std::vector<uint32_t> hits;
        for (size_t k = r.begin(); k != r.end(); ++k) {
            const size_t i = voxels[k];
            hits.clear();
            size_t allUsed = 0;   // rays that count, over all batches
            // Batch means; double sums (thousands of rays, values spread over decades).
            double mean[K][3] = {};
            for (int b = 0; b < K; ++b) {
                // A hash stream of its own, disjoint from the stored rays' (gamma-offset seed).
                const uint64_t h = mixHash(mixHash(mOptions.seed ^ 0x6A09E667F3BCC909ull)
                    ^ mixHash(uint64_t(i)) ^ mixHash(uint64_t(b) + 0xB7E151628AED2A6Bull));
                const CosineRays rays(mScene.normal(i), h, perBatch);
                double sum[3] = {};
                size_t used = 0;
                for (size_t s = 0; s < perBatch; ++s) {
                    const uint32_t y = trace(mScene, mPlanes, acc, box, uint32_t(i), rays(s));
                    if (y == kSky && mClosed[i]) continue;   // as iterate() does
                    ++used;
                    if (y >= kBack) continue;
                    hits.push_back(y);
                    for (int c = 0; c < channels; ++c) sum[c] += double(component(B[y], c));
                }
                for (int c = 0; c < channels; ++c) mean[b][c] = used ? sum[c] / double(used) : 0.0;
                allUsed += used;
            }
            // The stored pass's noise is common to all batches, so their spread misses it:
            // a voxel whose rays all land on one neighbour (tucked behind it on a staircase)
            // inherits that neighbour's error whole. Its variance, counting each voxel hit m
            // times of n rays as one error of weight m / n: sum (m / n)^2 err^2 (the stored
            // pass's own, conservative, estimate).
            std::sort(hits.begin(), hits.end());
            double carried[3] = {};
            const double n = double(allUsed);
            for (size_t a = 0; a < hits.size();) {
                size_t b = a;
                while (b < hits.size() && hits[b] == hits[a]) ++b;
                const double w = double(b - a) / std::max(n, 1.0);
                for (int c = 0; c < channels; ++c) {
                    const double err = component(storedError[hits[a]], c);
                    carried[c] += w * w * err * err;
                }
                a = b;
            }
            const ValueT e = vdbrad::value<ValueT>(mEmission, i);
            const ValueT rho = vdbrad::value<ValueT>(mScene.albedo(), i);
            for (int c = 0; c < channels; ++c) {
                double m = 0.0, ss = 0.0;
                for (int b = 0; b < K; ++b) m += mean[b][c];
                m /= K;
                for (int b = 0; b < K; ++b) ss += (mean[b][c] - m) * (mean[b][c] - m);
                const double p = component(rho, c);
                // The mean of K i.i.d. batch means: its variance is estimated without bias by
                // the batches' sample variance / K.
                setComponent(value[k], c, float(component(e, c) + p * m));
                setComponent(error[k], c,
                    float(p * std::sqrt(ss / double(K * (K - 1)) + carried[c])));
            }
        }
        const size_t d = done += r.size();
        if (interrupt && interrupt->wasInterrupted(int(100 * d / std::max<size_t>(voxels.size(), 1)))) {
            cancelled = true;
        }
    });
    if (cancelled) throw Cancelled("Monte Carlo final gather");
}

// Rays per batch of a gather of @a rays: rounded up, so that every batch has as many.
size_t
MonteCarloSolver::raysPerBatch(int rays)
{
    return (size_t(rays) + kGatherBatches - 1) / kGatherBatches;
}

MonteCarloGather
MonteCarloSolver::gather(const std::vector<size_t>& voxels, int rays,
    openvdb::util::NullInterrupter* interrupt) const
{
    if (rays < 1) OPENVDB_THROW(openvdb::ValueError, "gather rays must be >= 1, got " << rays);
    for (size_t i : voxels) {
        if (i >= mScene.size()) {
            OPENVDB_THROW(openvdb::ValueError, "gather voxel " << i << " out of range (scene has "
                << mScene.size() << " voxels)");
        }
    }
    const size_t perBatch = raysPerBatch(rays);
    MonteCarloGather g;
    if (mScene.isRgb()) gather(mRgb, mRgbError, voxels, perBatch, g.rgb, g.rgbError, interrupt);
    else gather(mGrey, mGreyError, voxels, perBatch, g.grey, g.greyError, interrupt);
    return g;
}

void
MonteCarloSolver::finalGather(int rays, openvdb::util::NullInterrupter* interrupt)
{
    std::vector<size_t> all(mScene.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = i;
    const auto t0 = std::chrono::steady_clock::now();
    MonteCarloGather g = gather(all, rays, interrupt);
    if (mScene.isRgb()) {
        mRgb.swap(g.rgb);
        mRgbError.swap(g.rgbError);
    } else {
        mGrey.swap(g.grey);
        mGreyError.swap(g.greyError);
    }
    mGathered = int(raysPerBatch(rays) * kGatherBatches);
    mIteration.addSeconds(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
}

void
MonteCarloSolver::solve(openvdb::util::NullInterrupter* interrupt)
{
    while (!finished()) iterate(interrupt);
}

std::string
MonteCarloSolver::describe(const Scene& scene, const MonteCarloOptions& options)
{
    return "Monte Carlo: " + withCommas(scene.size()) + " voxels, "
        + std::to_string(options.samples) + " rays each" + (scene.isRgb() ? ", RGB" : "");
}

openvdb::GridPtrVec
MonteCarloSolver::grids() const
{
    SolveStats stats;
    stats.directions = mGathered > 0 ? mGathered : mOptions.samples;
    stats.iterations = iterationCount();
    stats.residual = mIteration.lastResidual();
    stats.seconds = mIteration.seconds();
    stats.lines = "montecarlo";
    const std::string name = "radiosity_stderr";
    if (mScene.isRgb()) {
        return {makeRadiosityGrid(mScene, mRgb, stats),
            arrayToGrid(mScene.voxels(), mRgbError, mScene.transform(), name)};
    }
    return {makeRadiosityGrid(mScene, mGrey, stats),
        arrayToGrid(mScene.voxels(), mGreyError, mScene.transform(), name)};
}

openvdb::GridPtrVec
solveMonteCarlo(const Scene& scene, const MonteCarloOptions& options,
    openvdb::util::NullInterrupter* interrupt, const SolveControl& control)
{
    if (control.note) control.note(MonteCarloSolver::describe(scene, options));
    // Framed as one step, or (a caller reporting iterations) as steps of its own: the rays,
    // the iterations, the final gather.
    const bool framed = interrupt && !control.beforeIteration;
    const bool steps = interrupt && !framed;
    if (interrupt) interrupt->start(framed ? "Monte Carlo radiosity" : "casting rays");
    MonteCarloSolver solver(scene, options, interrupt);
    if (steps) interrupt->end();
    SolveControl loop = control;
    loop.note = nullptr;   // described above, before the rays
    iterateSolve(solver, loop, interrupt);
    if (options.gather > 0) {
        const std::string what = "final gather, " + std::to_string(options.gather)
            + " rays per voxel";
        if (steps) interrupt->start(what.c_str());
        solver.finalGather(options.gather, interrupt);
        if (steps) interrupt->end();
    }
    if (framed) interrupt->end();
    return solver.grids();
}

} // namespace vdbrad
