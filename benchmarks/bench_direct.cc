// Exact direct light against the sweeps' direct light, on lamps over a floor whose answer is
// closed-form (grids::makeLamp: floor radiosity rho E F(point -> emitter cells), Howell B-3).
// Error over the floor voxels where the exact value exceeds 5 % of its maximum: mean and 95th
// percentile of |B - exact| / exact. Time: the whole solve (direct light, sweeps, iterations),
// best of 2, with the ratio to the same scene's 1000-direction sweep-only solve.
//
//   build/benchmarks/bench_direct [res]      (default 128)
#include "BenchTiming.h"
#include "grids/CanonicalGrids.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/vdbrad.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <vector>

namespace {

struct Errors { double mean, p95; };

Errors
floorErrors(const vdbrad::Scene& scene, const std::vector<float>& B,
    const vdbrad::grids::BuildParams& p)
{
    std::vector<double> exact(scene.size(), -1.0);
    double top = 0.0;
    for (size_t i = 0; i < scene.size(); ++i) {
        const openvdb::Coord c = scene.voxels().coord(i);
        if (c.y() != 0) continue;
        exact[i] = vdbrad::grids::lampFloorRadiosity(p, c.x(), c.z());
        top = std::max(top, exact[i]);
    }
    std::vector<double> rel;
    for (size_t i = 0; i < scene.size(); ++i) {
        if (exact[i] > 0.05 * top) rel.push_back(std::abs(B[i] - exact[i]) / exact[i]);
    }
    std::sort(rel.begin(), rel.end());
    double sum = 0.0;
    for (double r : rel) sum += r;
    return {sum / double(rel.size()), rel[size_t(0.95 * double(rel.size() - 1))]};
}

} // namespace

int
main(int argc, char** argv)
{
    openvdb::initialize();
    const int res = argc > 1 ? std::atoi(argv[1]) : 128;
    std::printf("lamp over a floor, res %d; error where exact > 5 %% of its maximum\n", res);
    std::printf("%6s %6s %-22s %9s %9s %9s %7s\n", "r", "h", "method", "mean", "p95", "seconds",
        "ratio");
    struct Case { float r, h; };
    for (const Case& c : {Case{0.05f, 0.25f}, Case{0.02f, 0.1f}, Case{0.1f, 0.5f},
             Case{0.05f, 0.05f}}) {
        vdbrad::grids::BuildParams p;
        p.res = res;
        p.radius = c.r;
        p.height = c.h;
        const vdbrad::Scene scene = vdbrad::buildScene(vdbrad::grids::makeLamp(p));
        double baseline = 0.0;
        struct Run { const char* name; vdbrad::DirectMode mode; int dirs, samples; };
        for (const Run& run : {Run{"sweep, 300 dirs", vdbrad::DirectMode::Sweep, 300, 0},
                 Run{"sweep, 1000 dirs", vdbrad::DirectMode::Sweep, 1000, 0},
                 Run{"sweep, 3000 dirs", vdbrad::DirectMode::Sweep, 3000, 0},
                 Run{"exact, 300 dirs, 4", vdbrad::DirectMode::Exact, 300, 4},
                 Run{"exact, 300 dirs, 16", vdbrad::DirectMode::Exact, 300, 16},
                 Run{"exact, 1000 dirs, 16", vdbrad::DirectMode::Exact, 1000, 16}}) {
            vdbrad::RadiosityOptions o;
            o.directions = run.dirs;
            o.direct = run.mode;
            o.directSamples = std::max(run.samples, 1);
            std::vector<float> B;
            const double secs = vdbrad::bench::timeIt([&] {
                vdbrad::RadiositySolver solver(scene, o);
                solver.solve();
                B = solver.grey();
            }, 2);
            if (run.mode == vdbrad::DirectMode::Sweep && run.dirs == 1000) baseline = secs;
            const Errors e = floorErrors(scene, B, p);
            std::printf("%6.3f %6.3f %-22s %8.3f%% %8.3f%% %9.3f %7s\n", c.r, c.h, run.name,
                100.0 * e.mean, 100.0 * e.p95, secs, "");
            if (baseline > 0.0 && run.mode == vdbrad::DirectMode::Exact) {
                std::printf("%6s %6s %-22s %9s %9s %9s %6.2fx\n", "", "", "  vs 1000-dir sweep",
                    "", "", "", secs / baseline);
            }
        }
    }
    return 0;
}
