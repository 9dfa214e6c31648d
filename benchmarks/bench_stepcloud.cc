// The I3RC step cloud (grids::makeStepCloud: 32 periodic columns over 0.5 km, 0.25 km thick,
// optical thickness 2 and 18, Henyey-Greenstein g = 0.85, black ground) solved by the cloud
// sweeps, against a photon Monte Carlo of the same columns run in this process
// (tests/CloudReference.h columnsMonteCarlo: delta tracking, no code shared with the sweeps).
// The issue's four experiments: sun at 0 and 60 degrees (azimuth 0: photons travel towards +x,
// from the thin columns into the thick), single-scattering albedo 1 and 0.99. Prints domain
// reflectance and transmittance, their errors, the energy balance, sweeps and the process's CPU
// time (user + sys, getrusage) of each solve, the quantity SHDOM's figures give.
//
//   build/benchmarks/bench_stepcloud [res=64] (voxels along x, a multiple of 32; res / 2 layers)
//       [directions=auto] [source=linear|constant] [weights=harmonic|cells]
//       [accelerate=auto|none|anderson] (auto, or left out: CloudTransferOptions' defaults)
//       [photons=2000000] (0: no Monte Carlo) [order=auto]
//       [experiments=0:1,0:0.99,60:1,60:0.99] (zenith:omega0, comma-separated)
//       [minPeriod=-1] (CloudTransferOptions::minPeriod; the one-voxel depth along z is swept
//       in the x-y plane, never copied) [csv=-] (appends one row per experiment, for
//       scripts/plot-stepcloud.py; - for none) [ground=none] (a Lambertian ground's albedo
//       under the cloud, in the solve and the Monte Carlo; T is then the ground's irradiance)
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
    // Unset arguments (or "auto") leave CloudTransferOptions' defaults.
    auto arg = [&](int i) { return argc > i ? std::string(argv[i]) : std::string("auto"); };
    const int dirs = arg(2) == "auto" ? 0 : std::atoi(argv[2]);
    const vdbrad::CloudTransferOptions defaults;
    const bool linear = arg(3) == "auto" ? defaults.source == vdbrad::VoxelSource::Linear
                                         : arg(3) == "linear";
    const bool harmonic = arg(4) == "auto" ? defaults.harmonicWeights : arg(4) == "harmonic";
    const std::string accelerate = arg(5);
    const long photons = argc > 6 ? std::atol(argv[6]) : 2000000;
    const int order = arg(7) == "auto" ? -1 : std::atoi(argv[7]);
    const std::string list = argc > 8 ? argv[8] : "0:1,0:0.99,60:1,60:0.99";
    const int minPeriod = argc > 9 ? std::atoi(argv[9]) : -1;
    const bool grounded = argc > 11 && std::string(argv[11]) != "none";
    const double groundAlbedo = grounded ? std::atof(argv[11]) : 0.0;
    std::FILE* csv = argc > 10 && std::string(argv[10]) != "-" ? std::fopen(argv[10], "a") : nullptr;
    if (csv && std::ftell(csv) == 0) {
        std::fprintf(csv, "res,directions,order,source,weights,zenith,omega0,R,R_mc,R_stderr,T,"
            "T_mc,T_stderr,sweeps,cpu_s\n");
    }
    std::vector<std::pair<double, double>> experiments;
    for (size_t at = 0; at < list.size();) {
        const size_t comma = std::min(list.find(',', at), list.size());
        const std::string item = list.substr(at, comma - at);
        const size_t colon = item.find(':');
        experiments.emplace_back(std::atof(item.substr(0, colon).c_str()),
            std::atof(item.substr(colon + 1).c_str()));
        at = comma + 1;
    }
    std::printf("step cloud res %d (%d x %d x 1 voxels), %s directions asked, order %d, %s "
        "source, %s weights, acceleration %s, Monte Carlo %ld photons, ground %s\n", res, res,
        res / 2, arg(2).c_str(), order, linear ? "linear" : "constant",
        harmonic ? "harmonic" : "cell", accelerate.c_str(), photons,
        grounded ? argv[11] : "none (black)");
    std::printf("%6s %6s %9s %9s %8s %9s %9s %8s %10s %6s %8s %8s %s\n", "sun", "omega0",
        "R", "R MC", "error", "T", "T MC", "error", "balance", "sweeps", "CPU s", "wall s",
        "copies");
    std::string described;
    for (const auto& experiment : experiments) {
        const auto [zenith, omega0] = experiment;
        vdbrad::grids::BuildParams params;
        params.res = res;
        params.albedo = float(omega0);
        const vdbrad::Cloud cloud = vdbrad::buildCloud(vdbrad::grids::makeStepCloud(params));
        vdbrad::CloudTransferOptions o;
        o.periodic = true;
        o.directions = dirs;
        o.sunZenith = zenith;
        o.sunAzimuth = 0.0;
        o.phase = vdbrad::PhaseFunction::henyeyGreenstein(0.85);
        o.phaseOrder = order;
        o.source = linear ? vdbrad::VoxelSource::Linear : vdbrad::VoxelSource::Constant;
        o.harmonicWeights = harmonic;
        if (accelerate != "auto") o.accelerate = vdbrad::accelerationFromString(accelerate);
        o.minPeriod = minPeriod;
        if (grounded) o.groundAlbedo = groundAlbedo;
        vdbrad::bench::Spent spent;
        const auto solved = vdbrad::bench::solved<vdbrad::CloudTransfer>(spent, cloud, o);
        const vdbrad::CloudTransfer& transfer = *solved;
        const double cpu = spent.cpu, wall = spent.wall;
        const vdbrad::CloudBudget& b = transfer.budget();
        if (&experiments.front() == &experiment) described = transfer.describe();
        vdbrad::test::SlabResult mc;
        if (photons > 0) {
            vdbrad::test::ColumnsProblem p;
            for (int c = 0; c < 32; ++c) p.columnTau.push_back(c < 16 ? 2.0 : 18.0);
            p.omega0 = omega0, p.g = 0.85, p.theta0 = zenith, p.phi0 = 0.0;
            p.groundAlbedo = groundAlbedo;
            vdbrad::test::MonteCarloRun run;
            run.photons = uint64_t(photons);
            run.seed = 7;
            mc = vdbrad::test::columnsMonteCarlo(p, run);
        }
        const openvdb::Coord& k = transfer.copies();
        std::printf("%6.0f %6.3f %9.5f %9.5f %7.2f%% %9.5f %9.5f %7.2f%% %10.2e %6d %8.2f %8.2f "
            "%dx%dx%d   (MC stderr R %.5f T %.5f; direct T %.5f, MC %.5f)\n", zenith, omega0, b.albedo, mc.reflectance,
            photons > 0 ? 100.0 * (b.albedo / mc.reflectance - 1.0) : 0.0, b.transmittance,
            mc.transmittance,
            photons > 0 ? 100.0 * (b.transmittance / mc.transmittance - 1.0) : 0.0, b.balance(),
            transfer.iterationCount(), cpu, wall, k.x(), k.y(), k.z(), mc.reflectanceStderr,
            mc.transmittanceStderr, b.directTransmittance, mc.directTransmittance);
        std::fflush(stdout);
        if (csv) {
            std::fprintf(csv, "%d,%zu,%d,%s,%s,%g,%g,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%d,%.2f\n", res,
                transfer.directions().size(), vdbrad::CloudTransfer::phaseOrderFor(o),
                linear ? "linear" : "constant", harmonic ? "harmonic" : "cells", zenith, omega0,
                b.albedo, mc.reflectance, mc.reflectanceStderr, b.transmittance,
                mc.transmittance, mc.transmittanceStderr, transfer.iterationCount(), cpu);
            std::fflush(csv);
        }
    }
    if (csv) std::fclose(csv);
    std::printf("solver: %s\n", described.c_str());
    return 0;
}
