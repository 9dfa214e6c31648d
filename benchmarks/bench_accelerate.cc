// Sweeps and time to a given accuracy with and without Anderson acceleration (Acceleration.h),
// on surfaces whose answer is known: closed furnaces (exact E / (1 - rho)), a half-lit furnace
// and the RGB Cornell box (answers: plain iterations run to a 1e-9 residual). Plain and
// accelerated solves run in this process, one after the other; "ratio" = plain / accelerated.
// Clouds: bench_cloud ... both.
//
//   build/benchmarks/bench_accelerate [res=32] [directions=300] [target=1e-4]
#include "grids/CanonicalGrids.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/vdbrad.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

struct Run
{
    int sweeps = -1;        // first sweep after which the error is <= target (-1: never)
    double seconds = 0.0;   // solver time up to then (error evaluation excluded)
};

// Iterate until the error against @a exact (worst over voxels and channels, relative to
// max |exact|) is <= @a target, or @a cap sweeps.
Run
sweepsTo(const vdbrad::Scene& scene, vdbrad::RadiosityOptions o, const std::vector<float>& exact,
    double target, int cap)
{
    o.tolerance = 0.0;
    o.maxIterations = cap;
    double solveSeconds = 0.0;
    const auto t0 = Clock::now();
    vdbrad::RadiositySolver solver(scene, o);
    solveSeconds += std::chrono::duration<double>(Clock::now() - t0).count();
    double top = 0.0;
    for (float v : exact) top = std::max(top, double(std::abs(v)));
    Run run;
    while (solver.iterationCount() < cap) {
        const auto t1 = Clock::now();
        solver.iterate();
        solveSeconds += std::chrono::duration<double>(Clock::now() - t1).count();
        const float* b = scene.isRgb() ? reinterpret_cast<const float*>(solver.rgb().data())
                                       : solver.grey().data();
        double worst = 0.0;
        for (size_t i = 0; i < exact.size(); ++i) {
            worst = std::max(worst, double(std::abs(b[i] - exact[i])));
        }
        if (worst <= target * top) {
            run.sweeps = solver.iterationCount();
            run.seconds = solveSeconds;
            return run;
        }
    }
    run.seconds = solveSeconds;
    return run;
}

std::vector<float>
converged(const vdbrad::Scene& scene, vdbrad::RadiosityOptions o)
{
    o.tolerance = 1e-9;
    o.maxIterations = 100000;
    vdbrad::RadiositySolver solver(scene, o);
    solver.solve();
    if (scene.isRgb()) {
        const float* b = reinterpret_cast<const float*>(solver.rgb().data());
        return std::vector<float>(b, b + 3 * scene.size());
    }
    return solver.grey();
}

} // namespace

int
main(int argc, char** argv)
{
    openvdb::initialize();
    const int res = argc > 1 ? std::atoi(argv[1]) : 32;
    const int dirs = argc > 2 ? std::atoi(argv[2]) : 300;
    const double target = argc > 3 ? std::atof(argv[3]) : 1e-4;
    std::printf("res %d, %d directions asked, target: worst error <= %g of max B\n", res, dirs,
        target);
    std::printf("%-18s %6s %8s | %8s %9s | %8s %9s | %8s %8s\n", "scene", "rho", "voxels",
        "plain", "seconds", "anderson", "seconds", "sweeps", "time");

    auto report = [&](const std::string& name, const std::string& rho, const vdbrad::Scene& scene,
                      const std::vector<float>& exact, int cap) {
        vdbrad::RadiosityOptions o;
        o.directions = dirs;
        const Run plain = sweepsTo(scene, o, exact, target, cap);
        o.accelerate = vdbrad::Acceleration::Anderson;
        const Run fast = sweepsTo(scene, o, exact, target, cap);
        char p[16], f[16], r1[16], r2[16];
        auto count = [&](char* out, size_t size, int sweeps) {
            std::snprintf(out, size, sweeps > 0 ? "%d" : ">%d", sweeps > 0 ? sweeps : cap);
        };
        count(p, sizeof p, plain.sweeps);
        count(f, sizeof f, fast.sweeps);
        std::snprintf(r1, sizeof r1, plain.sweeps > 0 && fast.sweeps > 0 ? "%.1fx" : "-",
            double(plain.sweeps) / double(fast.sweeps));
        std::snprintf(r2, sizeof r2, plain.sweeps > 0 && fast.sweeps > 0 ? "%.1fx" : "-",
            plain.seconds / fast.seconds);
        std::printf("%-18s %6s %8zu | %8s %9.2f | %8s %9.2f | %8s %8s\n", name.c_str(),
            rho.c_str(), scene.size(), p, plain.seconds, f, fast.seconds, r1, r2);
        std::fflush(stdout);
    };

    for (const char* name : {"furnace-box", "furnace-sphere"}) {
        for (double rho : {0.5, 0.9, 0.99, 0.999}) {
            vdbrad::grids::BuildParams p;
            p.res = res;
            p.albedo = float(rho);
            p.emission = 1.f;
            const vdbrad::Scene scene =
                vdbrad::buildScene(vdbrad::grids::findBuilder(name)->build(p));
            report(name, std::to_string(rho).substr(0, 5), scene,
                std::vector<float>(scene.size(), float(1.0 / (1.0 - double(float(rho))))), 20000);
        }
    }
    // Half the furnace box emits: the solution is not along the first iterate.
    for (double rho : {0.9, 0.99, 0.999}) {
        vdbrad::grids::BuildParams p;
        p.res = res;
        p.albedo = float(rho);
        p.emission = 1.f;
        openvdb::GridPtrVec g = vdbrad::grids::makeFurnaceBox(p);
        for (auto& grid : g) {
            if (grid->getName() != "emission") continue;
            auto e = openvdb::gridPtrCast<openvdb::FloatGrid>(grid);
            for (auto it = e->beginValueOn(); it; ++it) {
                if (it.getCoord().x() >= res / 2) it.setValue(0.f);
            }
        }
        const vdbrad::Scene scene = vdbrad::buildScene(g);
        vdbrad::RadiosityOptions o;
        o.directions = dirs;
        o.update = vdbrad::UpdateScheme::Jacobi;
        report("half-lit box", std::to_string(rho).substr(0, 5), scene, converged(scene, o), 20000);
    }
    {
        vdbrad::grids::BuildParams p;
        p.res = res * 2;
        const vdbrad::Scene scene =
            vdbrad::buildScene(vdbrad::grids::findBuilder("cornell")->build(p));
        vdbrad::RadiosityOptions o;
        o.directions = dirs;
        report("cornell x2 res", "RGB", scene, converged(scene, o), 2000);
    }
    return 0;
}
