// Line structure: the streaming frontier pass (LineSweep::sweep, what the solver uses) against
// explicit per-line lists built by a stable counting sort (LineSweep::sweepLists, the thesis'
// structure), same visibility rule, same scene and directions, one thread, in one process.
//
//   build/benchmarks/bench_lines [res=256] [directions=100]
#include "grids/CanonicalGrids.h"
#include "vdbrad/sweep/DirectionSet.h"
#include "vdbrad/sweep/LineSweep.h"
#include "vdbrad/vdbrad.h"

#include <chrono>
#include <cstdio>
#include <cstdlib>

int
main(int argc, char** argv)
{
    openvdb::initialize();
    const int res = argc > 1 ? std::atoi(argv[1]) : 256;
    const int count = argc > 2 ? std::atoi(argv[2]) : 100;
    vdbrad::grids::BuildParams p;
    p.res = res;
    const vdbrad::Scene scene = vdbrad::buildScene(vdbrad::grids::makeCornell(p));
    const vdbrad::DirectionSet set = vdbrad::DirectionSet::fromCount(count);
    std::vector<float> B(scene.size(), 1.f);
    double frontier = 0.0, lists = 0.0, sink = 0.0;
    for (size_t d = 0; d < set.size(); ++d) {
        bool reversed = false;
        const vdbrad::LeafOrder order(scene.voxels(),
            vdbrad::LeafOrder::baseSigns(set.direction(d), reversed));
        const vdbrad::LineSweep sweep(scene.voxels(), order, &scene.normals(),
            vdbrad::LineType::Naive);
        std::vector<float> G(scene.size(), 0.f);
        vdbrad::LineSweep::Workspace<float> work;
        std::vector<uint32_t> starts, listed;
        auto load = [&](uint32_t y) { return B[y]; };
        auto visit = [&](uint32_t x, const float* seen, float dn) {
            if (seen) G[x] += *seen * std::abs(dn);
        };
        const auto t0 = std::chrono::steady_clock::now();
        sweep.sweep(set.direction(d), reversed, work, load, visit);
        const auto t1 = std::chrono::steady_clock::now();
        sweep.sweepLists(set.direction(d), reversed, work, starts, listed, load, visit);
        const auto t2 = std::chrono::steady_clock::now();
        frontier += std::chrono::duration<double>(t1 - t0).count();
        lists += std::chrono::duration<double>(t2 - t1).count();
        sink += G[0];
    }
    const double work = double(scene.size()) * double(set.size());
    std::printf("Cornell res %d, %zu voxels, %zu directions, 1 thread\n", res, scene.size(),
        set.size());
    std::printf("frontier (streaming) : %.2f ns per voxel.direction\n", 1e9 * frontier / work);
    std::printf("explicit line lists  : %.2f ns per voxel.direction (%.2fx the frontier)%s\n",
        1e9 * lists / work, lists / frontier, sink < 0 ? " " : "");
    return 0;
}
