// Solver speed: nanoseconds per voxel x direction x iteration of RadiositySolver on the Cornell
// box, on 1 and 2 threads, against two baselines run in the same process (one thread each):
//  - "stream": one pass per direction reading each voxel's coordinate and normal, without any
//    line logic: what any per-voxel, per-direction method must touch;
//  - "frontier": the bare exchange of a streaming line sweep, per direction (line slots computed
//    beforehand, not timed): both senses, each voxel swapping its RGB value with its line's
//    frontier entry and adding what it took to its accumulator, nothing else (no visibility
//    rule, no normals, no regions): the floor of any sweep that keeps a state per line.
//
// The first iteration sweeps every direction (and records what each voxel sees into the
// visibility cache); later ones replay the kept directions (RadiosityOptions::visibilityCache):
// both are printed, and their mean over the run.
//
//   build/benchmarks/bench_solver [res=512] [directions=1000] [iterations=4] [cacheMiB=all]
//
// cacheMiB 0: no cache, every iteration sweeps every direction.
#include "grids/CanonicalGrids.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/vdbrad.h"

#include <tbb/global_control.h>

#include <sys/resource.h>

#include "vdbrad/sweep/LinePartition.h"

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

int
main(int argc, char** argv)
{
    openvdb::initialize();
    const int res = argc > 1 ? std::atoi(argv[1]) : 512;
    const int dirs = argc > 2 ? std::atoi(argv[2]) : 1000;
    const int iterations = std::max(argc > 3 ? std::atoi(argv[3]) : 4, 1);
    const size_t cacheBytes = argc > 4 ? size_t(std::atoll(argv[4])) << 20 : SIZE_MAX;
    vdbrad::grids::BuildParams p;
    p.res = res;
    const vdbrad::Scene scene = vdbrad::buildScene(vdbrad::grids::makeCornell(p));
    std::printf("Cornell box res %d: %zu surface voxels, RGB\n", res, scene.size());

    // Baseline: per direction, one streaming pass over the voxels reading coordinate and normal
    // and accumulating a dot product: what any per-voxel, per-direction method must touch.
    const vdbrad::DirectionSet set = vdbrad::DirectionSet::fromCount(dirs);
    double frontierSeconds = 0.0, frontierSink = 0.0;
    {
        const size_t n = scene.size();
        const openvdb::CoordBBox box = scene.voxels().bbox();
        std::vector<uint32_t> slots(n);
        std::vector<openvdb::Vec3f> B(n, openvdb::Vec3f(1.f)), acc(n, openvdb::Vec3f(0.f));
        std::vector<openvdb::Vec3f> fronts;
        for (size_t k = 0; k < set.size(); ++k) {
            vdbrad::LinePartition part(set.direction(k), vdbrad::LineType::Naive);
            part.centreOn(box.min() + box.max());
            const vdbrad::LinePartition::BoxKeys keys(part, box);
            int64_t i0 = INT64_MAX, j0 = INT64_MAX, i1 = INT64_MIN, j1 = INT64_MIN;
            for (size_t v = 0; v < n; ++v) {
                const vdbrad::LineKey key = keys.key(scene.voxels().coord(v));
                i0 = std::min(i0, key.i); i1 = std::max(i1, key.i);
                j0 = std::min(j0, key.j); j1 = std::max(j1, key.j);
            }
            for (size_t v = 0; v < n; ++v) {
                const vdbrad::LineKey key = keys.key(scene.voxels().coord(v));
                slots[v] = uint32_t((key.i - i0) * (j1 - j0 + 1) + (key.j - j0));
            }
            fronts.assign(size_t((i1 - i0 + 1) * (j1 - j0 + 1)), openvdb::Vec3f(0.f));
            const auto f0 = std::chrono::steady_clock::now();
            for (size_t v = 0; v < n; ++v) {
                openvdb::Vec3f& f = fronts[slots[v]];
                acc[v] += f;
                f = B[v];
            }
            std::fill(fronts.begin(), fronts.end(), openvdb::Vec3f(0.f));
            for (size_t v = n; v-- > 0;) {
                openvdb::Vec3f& f = fronts[slots[v]];
                acc[v] += f;
                f = B[v];
            }
            frontierSeconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - f0)
                .count();
        }
        for (const openvdb::Vec3f& a : acc) frontierSink += a[0];
    }
    for (int threads : {1, 2}) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
        vdbrad::RadiosityOptions o;
        o.directions = dirs;
        o.maxIterations = iterations;
        o.tolerance = 0.0;
        o.visibilityCache = cacheBytes;
        const auto t0 = std::chrono::steady_clock::now();
        vdbrad::RadiositySolver solver(scene, o);
        const auto t1 = std::chrono::steady_clock::now();
        std::vector<double> each;
        std::vector<long> faults;   // minor page faults per iteration: first touches of memory
        for (int it = 0; it < iterations; ++it) {
            struct rusage r0, r1;
            getrusage(RUSAGE_SELF, &r0);
            const auto i0 = std::chrono::steady_clock::now();
            solver.iterate();
            each.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - i0)
                .count());
            getrusage(RUSAGE_SELF, &r1);
            faults.push_back(r1.ru_minflt - r0.ru_minflt);
        }
        const double setup = std::chrono::duration<double>(t1 - t0).count();
        const double per = double(scene.size()) * double(solver.directions().size()) * 1e-9;
        double later = 0.0;
        for (size_t it = 1; it < each.size(); ++it) later += each[it];
        const double all = each[0] + later;

        double sink = 0.0;
        const auto b0 = std::chrono::steady_clock::now();
        for (size_t k = 0; k < set.size(); ++k) {
            const openvdb::Vec3f s(set.unit(k));
            double acc = 0.0;
            for (size_t i = 0; i < scene.size(); ++i) {
                const float d = s.dot(scene.normal(i));
                acc += d > 0.f ? d * float(scene.voxels().coord(i).x()) : 0.f;
            }
            sink += acc;
        }
        const double base = std::chrono::duration<double>(std::chrono::steady_clock::now() - b0)
            .count();
        std::printf("threads %d: %zu directions, setup %.2f s, visibility cache %zu of %zu "
                    "directions (%.1f MiB, %.2f bytes per voxel.direction)\n",
            threads, solver.directions().size(), setup, solver.cachedDirections(),
            solver.directions().size(), double(solver.cacheBytes()) / (1 << 20),
            solver.cachedDirections() > 0 ? double(solver.cacheBytes())
                / (double(solver.cachedDirections()) * double(scene.size())) : 0.0);
        std::printf("  iteration 1 (sweeps): %.2f ns per voxel.direction (%.2f per core), "
                    "%ld page faults\n", each[0] / per, each[0] * threads / per, faults[0]);
        if (each.size() > 1) {
            const double mean = later / double(each.size() - 1);
            std::printf("  iterations 2-%zu (%s): %.2f ns (%.2f per core); each:", each.size(),
                solver.cachedDirections() == solver.directions().size() ? "replayed"
                : solver.cachedDirections() > 0 ? "partly replayed" : "sweeps",
                mean / per, mean * threads / per);
            for (size_t it = 1; it < each.size(); ++it) std::printf(" %.2f", each[it] / per);
            std::printf("; page faults each:");
            for (size_t it = 1; it < each.size(); ++it) std::printf(" %ld", faults[it]);
            std::printf("\n");
        }
        std::printf("  all %zu: %.2f ns per voxel.direction.iteration (%.2f per core); "
                    "baselines (1 thread): stream %.2f ns, frontier %.2f ns%s\n",
            each.size(), all / per / double(each.size()),
            all * threads / per / double(each.size()), base / per, frontierSeconds / per,
            sink + frontierSink == 42.0 ? " " : "");
    }
    return 0;
}
