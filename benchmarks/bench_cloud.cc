// The cloud sweeps on a homogeneous periodic slab (Henyey-Greenstein g, omega0, sun at the
// zenith) against the exact slab solution (adding-doubling, tests/CloudReference.h, which shares
// no code with the sweeps; for |g| > 0.95, beyond its quadrature, a 2e6-photon Monte Carlo):
// albedo, its error, transmittance and its exact value, energy balance, iterations, time, and
// the cost per voxel.direction.iteration. The slab is W x H x W voxels; periodic boundaries make
// it infinite.
//
//   build/benchmarks/bench_cloud [directions=300] [layers=20] [omega0=1] [width=4]
//                                [g=0, or a file of Legendre coefficients such as
//                                samples/phase/cloud_c1.txt] [order=8, -1 auto]
//                                [csv=] (appends rows, with the photon Monte Carlo and delta-
//                                Eddington albedos, for scripts/plot-cloud.py; - for none)
//                                [accelerate=none|anderson|both] (both: each slab is solved
//                                plain, then with Anderson acceleration, in this process)
//                                [taus=0.5,1,2,5,10,20,50] (total optical depths, comma-separated)
//                                [iterations=5000] (sweeps cap)
//                                [copies=none|auto|both] (CloudTransferOptions::minPeriod: none
//                                solves the W-wide box as given, auto as the default copies
//                                side by side, both each slab both ways, in this process, with
//                                the time ratio auto / none)
//                                [source=constant|linear] (CloudTransferOptions::source)
//                                [weights=cells|harmonic] (CloudTransferOptions::harmonicWeights)
#include "vdbrad/cloud/CloudTransfer.h"
#include "vdbrad/scene/Cloud.h"

#include "../tests/CloudReference.h"

#include <openvdb/openvdb.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

int
main(int argc, char** argv)
{
    openvdb::initialize();
    const int dirs = argc > 1 ? std::atoi(argv[1]) : 300;
    const int layers = argc > 2 ? std::atoi(argv[2]) : 20;
    const float omega0 = argc > 3 ? float(std::atof(argv[3])) : 1.f;
    const int width = argc > 4 ? std::atoi(argv[4]) : 4;
    // g, or a file of Legendre coefficients (PhaseFunction::readLegendre; adding-doubling sums
    // the series at 128 nodes, which integrate its 300 terms exactly).
    const std::string phaseArg = argc > 5 ? argv[5] : "0";
    char* gEnd = nullptr;
    const double gGiven = std::strtod(phaseArg.c_str(), &gEnd);
    const bool tabulated = *gEnd != '\0';
    const vdbrad::PhaseFunction phase = tabulated
        ? vdbrad::PhaseFunction::readLegendre(phaseArg)
        : vdbrad::PhaseFunction::henyeyGreenstein(gGiven);
    const double g = phase.asymmetry();
    std::vector<double> chi;
    for (int l = 0; tabulated && l < 100000 && (l == 0 || phase.chi(l) != 0.0); ++l) {
        chi.push_back(phase.chi(l));
    }
    const int order = argc > 6 ? std::atoi(argv[6]) : 8;
    if (tabulated && argc > 7 && std::string(argv[7]) != "-") {
        std::fprintf(stderr, "bench_cloud: the csv's Monte Carlo column is Henyey-Greenstein "
            "only: give - for csv with a phase file\n");
        return 2;
    }
    std::FILE* csv = argc > 7 && std::string(argv[7]) != "-" ? std::fopen(argv[7], "a") : nullptr;
    const std::string accelerate = argc > 8 ? argv[8] : "none";
    const std::string tauList = argc > 9 ? argv[9] : "0.5,1,2,5,10,20,50";
    std::vector<double> taus;
    for (size_t at = 0; at < tauList.size();) {
        const size_t comma = std::min(tauList.find(',', at), tauList.size());
        taus.push_back(std::atof(tauList.substr(at, comma - at).c_str()));
        at = comma + 1;
    }
    const int maxIterations = argc > 10 ? std::atoi(argv[10]) : 5000;
    const std::string copies = argc > 11 ? argv[11] : "none";
    const bool linear = argc > 12 && std::string(argv[12]) == "linear";
    const bool cells = !(argc > 13 && std::string(argv[13]) == "harmonic");
    std::vector<int> minPeriods;
    if (copies != "auto") minPeriods.push_back(0);
    if (copies != "none") minPeriods.push_back(-1);
    std::vector<vdbrad::Acceleration> modes;
    if (accelerate != "anderson") modes.push_back(vdbrad::Acceleration::None);
    if (accelerate != "none") modes.push_back(vdbrad::Acceleration::Anderson);
    if (csv && std::ftell(csv) == 0) {
        std::fprintf(csv, "g,tau,albedo,exact,monte_carlo,mc_stderr,delta_eddington,iterations,"
            "seconds,to1_iterations\n");
    }
    std::printf("periodic slab %d x %d x %d, %s g %.3f (order %d), omega0 %.3f, %d directions "
        "asked, %s source per voxel, %s weights\n", width, layers, width,
        tabulated ? phaseArg.c_str() : "HG", g, order, omega0, dirs,
        linear ? "linear" : "constant", cells ? "cell" : "harmonic");
    std::printf("%8s %9s %7s %10s %10s %8s %10s %10s %10s %10s %6s %8s %12s %12s\n", "tau",
        "accel", "copies", "albedo", "exact",
        "error", "transmit", "exact T", "absorb", "balance", "iters", "seconds", "ns/vox.dir",
        "to 1%: it/s");
    for (double tau : taus) {
        const double h = 1.0 / layers;
        openvdb::FloatGrid::Ptr density = openvdb::FloatGrid::create(0.f);
        density->setName("density");
        density->setTransform(openvdb::math::Transform::createLinearTransform(h));
        density->tree().fill(openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(width - 1, layers - 1, width - 1)),
            float(tau), true);
        density->tree().voxelizeActiveTiles();
        vdbrad::CloudOptions co;
        co.defaultAlbedo = omega0;
        const vdbrad::Cloud cloud = vdbrad::buildCloud({density}, co);
        vdbrad::CloudTransferOptions o;
        o.periodic = true;
        o.directions = dirs;
        o.tolerance = 1e-6;
        o.maxIterations = maxIterations;
        o.phase = phase;
        o.phaseOrder = order;
        o.source = linear ? vdbrad::VoxelSource::Linear : vdbrad::VoxelSource::Constant;
        o.harmonicWeights = !cells;
        vdbrad::test::SlabProblem problem;
        problem.tau = tau;
        problem.omega0 = omega0;
        problem.g = tabulated ? 0.0 : g;
        problem.legendre = chi;
        vdbrad::test::MonteCarloRun photons;
        photons.photons = 2000000;
        photons.seed = 5;
        const vdbrad::test::SlabResult reference = tabulated
            ? vdbrad::test::addingDoublingSlab(problem, 128)
            : std::abs(g) > 0.95 ? vdbrad::test::slabMonteCarlo(problem, photons)
                                 : vdbrad::test::addingDoublingSlab(problem);
        const double exact = reference.reflectance;
        for (const vdbrad::Acceleration mode : modes) {
        double asGiven = 0.0;
        for (const int minPeriod : minPeriods) {
        o.accelerate = mode;
        o.minPeriod = minPeriod;
        const auto t0 = std::chrono::steady_clock::now();
        vdbrad::CloudTransfer transfer(cloud, o);
        // Iterate by hand to note when the albedo first comes (and stays) within 1% of exact.
        int within = -1;
        double withinSeconds = 0.0;
        while (!transfer.converged() && transfer.iterationCount() < o.maxIterations) {
            transfer.iterate();
            const bool ok = std::abs(transfer.budget().albedo - exact) <= 0.01 * exact;
            if (ok && within < 0) {
                within = transfer.iterationCount();
                withinSeconds = std::chrono::duration<double>(
                    std::chrono::steady_clock::now() - t0).count();
            } else if (!ok) {
                within = -1;
            }
        }
        const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        const vdbrad::CloudBudget& b = transfer.budget();
        char to1[32];
        if (within > 0) std::snprintf(to1, sizeof to1, "%d / %.2f", within, withinSeconds);
        else std::snprintf(to1, sizeof to1, "never");
        if (csv) {
            vdbrad::test::MonteCarloRun run;
            run.photons = 1000000;
            const vdbrad::test::SlabResult mc = vdbrad::test::slabMonteCarlo(problem, run);
            std::fprintf(csv, "%g,%g,%.6f,%.6f,%.6f,%.6f,%.6f,%d,%.3f,%d\n", g, tau, b.albedo, exact,
                mc.reflectance, mc.reflectanceStderr,
                vdbrad::test::deltaEddingtonAlbedo(tau, omega0, g, 1.0),
                transfer.iterationCount(), s, within);
        }
        const openvdb::Coord c = transfer.copies();
        char tiles[32];
        std::snprintf(tiles, sizeof tiles, "%dx%d", c.x(), c.z());
        std::printf("%8.3g %9s %7s %10.5f %10.5f %7.2f%% %10.5f %10.5f %10.5f %10.2e %6d %8.2f "
            "%12.1f %12s", tau, vdbrad::toString(mode), tiles, b.albedo, exact,
            100.0 * (b.albedo - exact) / exact, b.transmittance, reference.transmittance,
            b.absorptance, b.balance(), transfer.iterationCount(), s,
            1e9 * s / (double(cloud.size()) * c.x() * c.y() * c.z()
                * double(transfer.directions().size()) * transfer.iterationCount()), to1);
        if (minPeriod == 0) asGiven = s;
        else if (asGiven > 0.0) std::printf("  time %.1fx as given", s / asGiven);
        std::printf("\n");
        }
        }
    }
    if (csv) std::fclose(csv);
    return 0;
}
