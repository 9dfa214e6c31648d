// Solver speed: nanoseconds per voxel x direction x iteration of RadiositySolver on the Cornell
// box, on 1 and 2 threads, against a baseline run in the same process: one pass that touches the
// same per-voxel data (coordinates, normals, the gathered value) without any line logic, i.e. the
// memory traffic floor of a sweep.
//
//   build/benchmarks/bench_solver [res=512] [directions=1000] [iterations=1]
#include "grids/CanonicalGrids.h"
#include "vdbrad/RadiositySolver.h"
#include "vdbrad/vdbrad.h"

#include <tbb/global_control.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>

int
main(int argc, char** argv)
{
    openvdb::initialize();
    const int res = argc > 1 ? std::atoi(argv[1]) : 512;
    const int dirs = argc > 2 ? std::atoi(argv[2]) : 1000;
    const int iterations = argc > 3 ? std::atoi(argv[3]) : 1;
    vdbrad::grids::BuildParams p;
    p.res = res;
    const vdbrad::Scene scene = vdbrad::buildScene(vdbrad::grids::makeCornell(p));
    std::printf("Cornell box res %d: %zu surface voxels, RGB\n", res, scene.size());

    // Baseline: per direction, one streaming pass over the voxels reading coordinate and normal
    // and accumulating a dot product: what any per-voxel, per-direction method must touch.
    const vdbrad::DirectionSet set = vdbrad::DirectionSet::fromCount(dirs);
    for (int threads : {1, 2}) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
        vdbrad::RadiosityOptions o;
        o.directions = dirs;
        o.maxIterations = iterations;
        o.tolerance = 0.0;
        const auto t0 = std::chrono::steady_clock::now();
        vdbrad::RadiositySolver solver(scene, o);
        const auto t1 = std::chrono::steady_clock::now();
        solver.solve();
        const auto t2 = std::chrono::steady_clock::now();
        const double setup = std::chrono::duration<double>(t1 - t0).count();
        const double solve = std::chrono::duration<double>(t2 - t1).count();
        const double work = double(scene.size()) * double(solver.directions().size()) * iterations;

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
            .count() * iterations;
        std::printf("threads %d: %zu directions, setup %.2f s, %d iteration(s) %.2f s: "
                    "%.2f ns per voxel.direction.iteration (%.2f ns x threads); baseline pass "
                    "%.2f ns (1 thread): ratio %.1fx%s\n", threads, solver.directions().size(),
            setup, iterations, solve, 1e9 * solve / work, 1e9 * solve * threads / work,
            1e9 * base / work, (solve * threads) / base, sink == 42.0 ? " " : "");
    }
    return 0;
}
