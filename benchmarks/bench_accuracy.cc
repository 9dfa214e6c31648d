// Accuracy against exact references: the disk's on-axis receiver irradiance (Howell B-13,
// E r^2 / (r^2 + h^2) = 0.5) for several direction counts and resolutions, with the solve time.
// The direct light goes through the sweeps (--direct sweep), whose accuracy this measures: exact
// direct light, the default, gives it to rounding (bench_direct).
//
//   build/benchmarks/bench_accuracy [res ...]      (default 32 64 128)
#include "grids/CanonicalGrids.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/vdbrad.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

int
main(int argc, char** argv)
{
    openvdb::initialize();
    std::vector<int> resolutions;
    for (int i = 1; i < argc; ++i) resolutions.push_back(std::atoi(argv[i]));
    if (resolutions.empty()) resolutions = {32, 64, 128};
    std::printf("%5s %9s %10s %12s %9s\n", "res", "voxels", "directions", "axis error", "seconds");
    for (int res : resolutions) {
        vdbrad::grids::BuildParams p;
        p.res = res;
        const vdbrad::Scene scene = vdbrad::buildScene(vdbrad::grids::makeDisk(p));
        const double vs = scene.voxelSize();
        for (int dirs : {50, 100, 300, 1000, 3000, 10000}) {
            vdbrad::RadiosityOptions o;
            o.directions = dirs;
            o.maxIterations = 2;   // receiver albedo 1, emitter albedo 0: exact after two
            o.tolerance = 0.0;
            o.direct = vdbrad::DirectMode::Sweep;
            const auto t0 = std::chrono::steady_clock::now();
            vdbrad::RadiositySolver solver(scene, o);
            solver.solve();
            const double secs = std::chrono::duration<double>(
                std::chrono::steady_clock::now() - t0).count();
            // Mean over the receiver voxels within one voxel of the axis, against the exact
            // irradiance at each one's position.
            double sum = 0.0, exact = 0.0;
            for (size_t i = 0; i < scene.size(); ++i) {
                const openvdb::Coord c = scene.voxels().coord(i);
                if (c.y() == 0) continue;
                const double x = (c.x() + 0.5) * vs - 0.5, z = (c.z() + 0.5) * vs - 0.5;
                const double a = std::sqrt(x * x + z * z);
                if (a > vs) continue;
                sum += solver.grey()[i];
                exact += vdbrad::grids::diskIrradiance(1.0, 0.25, c.y() * vs, a);
            }
            std::printf("%5d %9zu %10zu %11.4f%% %9.3f\n", res, scene.size(),
                solver.directions().size(), 100.0 * std::abs(sum - exact) / exact, secs);
        }
    }
    return 0;
}
