// Fog inside a surface scene (FogSurfaces.h): the Cornell box with and without fog.
//
//   bench_fog_room [res=32] [directions=300] [tau=1] [samples=256] [gather=2048]
//
// 1. Fog-free room: the transfer with the walls as its surfaces (a fog of optical depth 1e-6)
//    against a Monte Carlo reference of the same voxels (MonteCarloSolver, `samples` rays per
//    voxel and a final gather), beside the surface solver with its light swept (the method as
//    published) and with exact direct light, same directions: mean |B - B_ref| / mean B_ref over
//    the voxels and channels, and CPU seconds (user + sys) for each.
// 2. The foggy room (make cornell --tau): per channel, iterations, energy balance, what the fog
//    and the walls absorb and what leaves through the open front; CPU seconds.
#include "vdbrad/cloud/CloudTransfer.h"
#include "vdbrad/reference/MonteCarloSolver.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/surface/DirectLight.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "grids/CanonicalGrids.h"
#include "BenchTiming.h"

#include <openvdb/openvdb.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

using namespace vdbrad;
using openvdb::Coord;

namespace {

// The Cornell box's air as a fog of @a tau across the room's width (make cornell --tau).
Cloud
roomFog(int res, double tau)
{
    grids::BuildParams p;
    p.res = res;
    p.tau = float(tau);
    for (const openvdb::GridBase::Ptr& g : grids::makeCornell(p)) {
        if (g->getName() == "density") return buildCloud({g});
    }
    std::fprintf(stderr, "no density grid\n");
    std::exit(1);
}

double
meanRelative(const openvdb::Vec3SGrid& a, const openvdb::Vec3SGrid& ref)
{
    double diff = 0.0, sum = 0.0;
    auto acc = a.getConstAccessor();
    for (auto it = ref.cbeginValueOn(); it; ++it) {
        const openvdb::Vec3f r = *it, v = acc.getValue(it.getCoord());
        for (int c = 0; c < 3; ++c) {
            diff += std::abs(double(v[c]) - double(r[c]));
            sum += std::abs(double(r[c]));
        }
    }
    return sum > 0.0 ? diff / sum : 0.0;
}

} // namespace

int
main(int argc, char** argv)
{
    openvdb::initialize();
    const int res = argc > 1 ? std::atoi(argv[1]) : 32;
    const int dirs = argc > 2 ? std::atoi(argv[2]) : 300;
    const double tau = argc > 3 ? std::atof(argv[3]) : 1.0;
    const int samples = argc > 4 ? std::atoi(argv[4]) : 256;
    const int gather = argc > 5 ? std::atoi(argv[5]) : 2048;
    grids::BuildParams p;
    p.res = res;
    const Scene scene = buildScene(grids::makeCornell(p));
    std::printf("Cornell box res %d (%zu surface voxels), %d directions\n", res, scene.size(),
        dirs);

    // 1. Fog-free: three solvers against Monte Carlo.
    openvdb::Vec3SGrid::Ptr mc;
    MonteCarloOptions mo;
    mo.samples = samples;
    mo.gather = gather;
    const bench::Spent tMc = bench::spent([&] {
        mc = openvdb::gridPtrCast<openvdb::Vec3SGrid>(solveMonteCarlo(scene, mo).front());
    });
    std::printf("  Monte Carlo reference (%d samples, gather %d): %.1f s CPU\n", samples,
        gather, tMc.cpu);
    for (DirectMode mode : {DirectMode::Sweep, DirectMode::Exact}) {
        RadiosityOptions ro;
        ro.directions = dirs;
        ro.direct = mode;
        openvdb::Vec3SGrid::Ptr B;
        const bench::Spent t = bench::spent([&] {
            B = openvdb::gridPtrCast<openvdb::Vec3SGrid>(solveRadiosity(scene, ro));
        });
        std::printf("  surface solver, %s direct light: mean error %.2f %%, %.1f s CPU\n",
            mode == DirectMode::Sweep ? "swept" : "exact", 100.0 * meanRelative(*B, *mc), t.cpu);
    }
    {
        const Cloud clear = roomFog(res, 1e-6);
        CloudTransferOptions o;
        o.surfaces = &scene;
        o.irradiance = 0.0;
        o.directions = dirs;
        openvdb::GridBase::Ptr radiosity;
        const bench::Spent t = bench::spent([&] {
            solveCloud(clear, o, nullptr, SolveControl(), nullptr, &radiosity);
        });
        std::printf("  transfer with surfaces (fog tau 1e-6, swept light): mean error %.2f %%, "
            "%.1f s CPU\n", 100.0 * meanRelative(
                *openvdb::gridPtrCast<openvdb::Vec3SGrid>(radiosity), *mc), t.cpu);
    }

    // 2. The foggy room.
    const Cloud fog = roomFog(res, tau);
    std::printf("foggy room: tau %g across, %zu fog voxels\n", tau, fog.size());
    for (int c = 0; c < 3; ++c) {
        CloudTransferOptions o;
        o.surfaces = &scene;
        o.channel = c;
        o.irradiance = 0.0;
        o.directions = dirs;
        CloudTransfer t(fog, o);
        const bench::Spent s = bench::spent([&] { t.solve(); });
        const CloudBudget& b = t.budget();
        std::printf("  channel %c: %d iterations, %.1f s CPU, fog absorbs %.4f, walls %.4f, "
            "out of the front %.4f, balance %.1e\n", "rgb"[c], t.iterationCount(), s.cpu,
            b.absorptance, b.surfaceAbsorptance, b.albedo + b.transmittance, b.balance());
    }
    return 0;
}
