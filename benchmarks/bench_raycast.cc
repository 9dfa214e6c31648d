// Head-to-head: the line-sweep solver against the ray-casting reference (RayCastVisibility) at
// equal directions on the Cornell box, one iteration each, all cores, in one process; also
// prints how far apart their results are (both use the same lines and rule: expect 0).
//
//   build/benchmarks/bench_raycast [res=256] [directions=50]
#include "grids/CanonicalGrids.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/vdbrad.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>

int
main(int argc, char** argv)
{
    openvdb::initialize();
    const int res = argc > 1 ? std::atoi(argv[1]) : 256;
    const int dirs = argc > 2 ? std::atoi(argv[2]) : 50;
    vdbrad::grids::BuildParams p;
    p.res = res;
    const vdbrad::Scene scene = vdbrad::buildScene(vdbrad::grids::makeCornell(p));

    double seconds[2] = {0.0, 0.0};
    std::vector<openvdb::Vec3f> result[2];
    size_t directions = 0;
    for (int method = 0; method < 2; ++method) {
        vdbrad::RadiosityOptions o;
        o.directions = dirs;
        o.maxIterations = 1;
        o.tolerance = 0.0;
        o.visibility = method == 0 ? vdbrad::Visibility::Sweep : vdbrad::Visibility::RayCast;
        const auto t0 = std::chrono::steady_clock::now();
        vdbrad::RadiositySolver solver(scene, o);
        solver.solve();
        seconds[method] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
            .count();
        result[method] = solver.rgb();
        directions = solver.directions().size();
    }
    double worst = 0.0, maxB = 0.0;
    for (size_t i = 0; i < scene.size(); ++i) {
        for (int c = 0; c < 3; ++c) {
            maxB = std::max(maxB, double(result[0][i][c]));
            worst = std::max(worst, std::abs(double(result[0][i][c]) - double(result[1][i][c])));
        }
    }
    const double work = double(scene.size()) * double(directions);
    std::printf("Cornell res %d, %zu voxels, %zu directions, 1 iteration (setup included)\n", res,
        scene.size(), directions);
    std::printf("sweep   %8.2f s  %9.1f ns per voxel.direction\n", seconds[0],
        1e9 * seconds[0] / work);
    std::printf("raycast %8.2f s  %9.1f ns per voxel.direction\n", seconds[1],
        1e9 * seconds[1] / work);
    std::printf("raycast / sweep = %.1fx; max |difference| / max B = %.3g\n",
        seconds[1] / seconds[0], worst / maxB);
    return 0;
}
