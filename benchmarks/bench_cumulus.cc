// A sparse 3D cloud (grids::makeCumulus: a procedural cumulus, conservative, in an open box)
// solved by the cloud sweeps, against a photon Monte Carlo of the same voxels run in this process
// (tests/CloudReference.h voxelMediumMonteCarlo: delta tracking through the piecewise-constant
// voxels, no code shared with the sweeps). Henyey-Greenstein phase, sun at the given zenith
// (azimuth 0). Prints the reflectance and transmittance (fractions of the beam power entering
// the box), their errors, the energy balance, sweeps and the CPU time (user + sys) of each solve.
//
//   build/benchmarks/bench_cumulus [res=64] [directions=auto,...] (comma-separated: one solve
//       each) [g=0.85] [zenith=40] [photons=2000000] [optical diameter tau=-1 (the builder's)]
//       [ground=none]
#include "vdbrad/cloud/CloudTransfer.h"
#include "vdbrad/scene/Cloud.h"

#include "BenchTiming.h"

#include "../grids/CanonicalGrids.h"
#include "../tests/CloudReference.h"

#include <openvdb/openvdb.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

int
main(int argc, char** argv)
{
    openvdb::initialize();
    const int res = argc > 1 ? std::atoi(argv[1]) : 64;
    const std::string list = argc > 2 ? argv[2] : "auto";
    const double g = argc > 3 ? std::atof(argv[3]) : 0.85;
    const double zenith = argc > 4 ? std::atof(argv[4]) : 40.0;
    const long photons = argc > 5 ? std::atol(argv[5]) : 2000000;
    const float tau = argc > 6 ? float(std::atof(argv[6])) : -1.f;
    const bool grounded = argc > 7 && std::string(argv[7]) != "none";
    const double groundAlbedo = grounded ? std::atof(argv[7]) : 0.0;

    vdbrad::grids::BuildParams params;
    params.res = res;
    params.tau = tau;
    const vdbrad::Cloud cloud = vdbrad::buildCloud(vdbrad::grids::makeCumulus(params));
    const openvdb::CoordBBox box = cloud.voxels().bbox();
    const openvdb::Coord dim = box.dim();
    double maxDepth = 0.0;
    for (float e : cloud.extinctionArray()) maxDepth = std::max(maxDepth, double(e));
    std::printf("cumulus res %d: %zu voxels in a %d x %d x %d box, max optical depth per voxel "
        "%.3f; HG g %g, sun %g deg, open box, ground %s; Monte Carlo %ld photons\n", res,
        cloud.size(), dim.x(), dim.y(), dim.z(), maxDepth * cloud.voxelSize(), g, zenith,
        grounded ? argv[7] : "none", photons);

    vdbrad::test::SlabResult mc;
    if (photons > 0) {
        vdbrad::test::VoxelMediumProblem p;
        p.nx = dim.x(), p.ny = dim.y(), p.nz = dim.z();
        p.h = cloud.voxelSize();
        p.sigma.assign(size_t(p.nx) * size_t(p.ny) * size_t(p.nz), 0.0);
        for (size_t i = 0; i < cloud.size(); ++i) {
            const openvdb::Coord c = cloud.voxels().coord(i) - box.min();
            p.sigma[size_t(c.x()) + size_t(p.nx) * (size_t(c.y()) + size_t(p.ny) * size_t(c.z()))]
                = cloud.extinction(i);
        }
        p.omega0 = cloud.albedo().grey(0);
        p.g = g;
        p.theta0 = zenith;
        p.groundAlbedo = groundAlbedo;
        vdbrad::test::MonteCarloRun run;
        run.photons = uint64_t(photons);
        run.seed = 7;
        const double cpu0 = vdbrad::bench::processCpuSeconds();
        mc = vdbrad::test::voxelMediumMonteCarlo(p, run);
        std::printf("Monte Carlo: R %.5f +- %.5f, T %.5f +- %.5f, A %.5f (%.1f s CPU)\n",
            mc.reflectance, mc.reflectanceStderr, mc.transmittance, mc.transmittanceStderr,
            mc.absorptance, vdbrad::bench::processCpuSeconds() - cpu0);
    }
    std::printf("%10s %6s %9s %8s %9s %8s %10s %6s %8s %8s\n", "directions", "order", "R",
        "error", "T", "error", "balance", "sweeps", "CPU s", "wall s");
    for (size_t at = 0; at < list.size();) {
        const size_t comma = std::min(list.find(',', at), list.size());
        const std::string item = list.substr(at, comma - at);
        at = comma + 1;
        vdbrad::CloudTransferOptions o;
        o.directions = item == "auto" ? 0 : std::atoi(item.c_str());
        o.sunZenith = zenith;
        o.phase = vdbrad::PhaseFunction::henyeyGreenstein(g);
        if (grounded) o.groundAlbedo = groundAlbedo;
        vdbrad::bench::Spent spent;
        const auto solved = vdbrad::bench::solved<vdbrad::CloudTransfer>(spent, cloud, o);
        const vdbrad::CloudTransfer& transfer = *solved;
        const double cpu = spent.cpu, wall = spent.wall;
        const vdbrad::CloudBudget& b = transfer.budget();
        std::printf("%10zu %6d %9.5f %7.2f%% %9.5f %7.2f%% %10.2e %6d %8.1f %8.1f\n",
            transfer.directions().size(), vdbrad::CloudTransfer::phaseOrderFor(o), b.albedo,
            photons > 0 ? 100.0 * (b.albedo / mc.reflectance - 1.0) : 0.0, b.transmittance,
            photons > 0 ? 100.0 * (b.transmittance / mc.transmittance - 1.0) : 0.0, b.balance(),
            transfer.iterationCount(), cpu, wall);
        std::fflush(stdout);
        if (at > list.size()) std::printf("solver: %s\n", transfer.describe().c_str());
    }
    return 0;
}
