// Issue 8's extremes, measured (tables in docs/journal/2026-12-01-extremes.md):
//  1. the furnace box across albedos from 0 to 1 - 1e-6: sweeps to 1e-4 of E / (1 - rho) with
//     plain in-place sweeps and with Anderson, and the error where each stops, in the precision
//     Precision::Auto picks and, above 0.999, also forced to float; then the cost of the double
//     state: seconds per sweep of the same solves in float and in double;
//  2. denormals: the same surface and cloud problems with every value scaled down into float's
//     denormal range (the solvers are linear, so only the magnitudes differ), time per sweep
//     against the unscaled run in this process ("ratio" = scaled / unscaled);
//  3. a scene of >= 1e7 surface voxels (furnace box at res >= 1300), solved to 1e-6 with Anderson:
//     voxels, seconds per sweep, error against the exact answer, peak memory.
//
//   build/benchmarks/bench_extremes [big-res=1300] [big-directions=50]   (big-res 0: skip part 3)
//
// The closed-cavity analysis alone (Enclosure's findRegions, the setup step that dominated
// part 3), the block fill against the former dense fill (tests/DenseRegions.h) in this process,
// on furnace boxes at each RES given, both line types; a negative RES times the block fill only:
//
//   build/benchmarks/bench_extremes enclosure 256 512 -1300
#include "grids/CanonicalGrids.h"
#include "tests/DenseRegions.h"
#include "vdbrad/cloud/CloudTransfer.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/sweep/Enclosure.h"
#include "vdbrad/vdbrad.h"

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;

double
since(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

vdbrad::Scene
furnace(int res, float rho, float emission, bool halfLit)
{
    vdbrad::grids::BuildParams p;
    p.res = res;
    p.albedo = rho;
    p.emission = emission;
    openvdb::GridPtrVec g = vdbrad::grids::makeFurnaceBox(p);
    if (halfLit) {
        for (auto& grid : g) {
            if (grid->getName() != "emission") continue;
            auto e = openvdb::gridPtrCast<openvdb::FloatGrid>(grid);
            for (auto it = e->beginValueOn(); it; ++it) {
                if (it.getCoord().x() >= res / 2) it.setValue(0.f);
            }
        }
    }
    return vdbrad::buildScene(g);
}

// Part 1: sweeps until every voxel is within 1e-4 of E / (1 - rho), at most @a cap.
void
albedoTable()
{
    std::printf("1. furnace box res 16, 50 directions, E = 1: sweeps to 1e-4 relative "
                "(error after the last sweep)\n");
    std::printf("%-12s %-7s | %16s %10s | %16s %10s\n", "rho", "state", "in-place sweeps",
        "error", "Anderson sweeps", "error");
    struct Row { double rho; vdbrad::Precision precision; };
    const Row rows[] = {{0.0, vdbrad::Precision::Auto}, {1e-6, vdbrad::Precision::Auto},
        {0.5, vdbrad::Precision::Auto}, {0.99, vdbrad::Precision::Auto},
        {0.999, vdbrad::Precision::Auto}, {0.9999, vdbrad::Precision::Float},
        {0.9999, vdbrad::Precision::Auto}, {1.0 - 1e-6, vdbrad::Precision::Float},
        {1.0 - 1e-6, vdbrad::Precision::Auto}};
    for (const Row& row : rows) {
        const double rho = row.rho;
        const vdbrad::Scene scene = furnace(16, float(rho), 1.f, false);
        const double exact = 1.0 / (1.0 - double(float(rho)));
        std::string cells[2][2];
        bool wide = false;
        for (int accel = 0; accel < 2; ++accel) {
            vdbrad::RadiosityOptions o;
            o.directions = 50;
            o.tolerance = 0.0;
            o.precision = row.precision;
            o.accelerate = accel ? vdbrad::Acceleration::Anderson : vdbrad::Acceleration::None;
            const int cap = accel ? 200 : 20000;
            vdbrad::RadiositySolver solver(scene, o);
            wide = solver.doublePrecision();
            int reached = -1;
            double error = 0.0;
            while (solver.iterationCount() < cap) {
                solver.iterate();
                error = 0.0;
                for (float b : solver.grey()) {
                    error = std::max(error, std::abs(double(b) - exact) / exact);
                }
                if (reached < 0 && error <= 1e-4) reached = solver.iterationCount();
                if (reached > 0 && solver.residuals().back() < 1e-9) break;
            }
            char buf[32];
            std::snprintf(buf, sizeof buf, reached > 0 ? "%d" : ">%d", reached > 0 ? reached : cap);
            cells[accel][0] = buf;
            std::snprintf(buf, sizeof buf, "%.2g", error);
            cells[accel][1] = buf;
        }
        std::printf("%-12.7g %-7s | %16s %10s | %16s %10s\n", rho, wide ? "double" : "float",
            cells[0][0].c_str(), cells[0][1].c_str(), cells[1][0].c_str(), cells[1][1].c_str());
        std::fflush(stdout);
    }

    // What the double state costs where it is not needed: the same solves forced to each.
    std::printf("\n1b. seconds per sweep, float vs double state (sweeps 2-4; the first also "
                "measures hit weights)\n");
    std::printf("%-40s %10s %10s %8s %12s\n", "problem", "float", "double", "ratio",
        "max |diff|");
    const struct { const char* name; vdbrad::Scene scene; int directions; } problems[] = {
        {"furnace box res 96, rho 0.9, grey", furnace(96, 0.9f, 1.f, false), 300},
        {"Cornell box res 96, RGB", vdbrad::buildScene(vdbrad::grids::makeCornell([] {
            vdbrad::grids::BuildParams p;
            p.res = 96;
            return p;
        }())), 300},
    };
    for (const auto& problem : problems) {
        double seconds[2];
        std::vector<openvdb::Vec3f> result[2];
        for (int wide = 0; wide < 2; ++wide) {
            vdbrad::RadiosityOptions o;
            o.directions = problem.directions;
            o.tolerance = 0.0;
            o.precision = wide ? vdbrad::Precision::Double : vdbrad::Precision::Float;
            vdbrad::RadiositySolver solver(problem.scene, o);
            solver.iterate();
            const auto t0 = Clock::now();
            for (int k = 0; k < 3; ++k) solver.iterate();
            seconds[wide] = since(t0) / 3;
            if (problem.scene.isRgb()) result[wide] = solver.rgb();
            else for (float b : solver.grey()) result[wide].emplace_back(b);
        }
        double diff = 0.0, top = 0.0;
        for (size_t i = 0; i < result[0].size(); ++i) {
            for (int c = 0; c < 3; ++c) {
                diff = std::max(diff, double(std::abs(result[0][i][c] - result[1][i][c])));
                top = std::max(top, double(result[1][i][c]));
            }
        }
        std::printf("%-40s %10.4f %10.4f %7.2fx %12.2g\n", problem.name, seconds[0], seconds[1],
            seconds[1] / seconds[0], top > 0.0 ? diff / top : 0.0);
        std::fflush(stdout);
    }
}

size_t
countDenormals(const float* v, size_t n)
{
    size_t k = 0;
    for (size_t i = 0; i < n; ++i) k += std::fpclassify(v[i]) == FP_SUBNORMAL;
    return k;
}

// Part 2: seconds per sweep with all values scaled by @a scale, against scale 1.
void
denormalTimes()
{
    std::printf("\n2. denormals: seconds per sweep, unscaled vs every value scaled into the "
                "denormal range\n");
    std::printf("%-44s %10s %10s %8s %14s\n", "problem", "unscaled", "scaled", "ratio",
        "denormal out");
    {
        // Half-lit furnace box, albedo 0.5: B ~ E, the gathered products w B ~ 1e-3 E.
        const int sweeps = 6;
        double seconds[2];
        size_t denormals = 0, n = 0;
        for (int k = 0; k < 2; ++k) {
            const vdbrad::Scene scene = furnace(64, 0.5f, k ? 1e-37f : 1.f, true);
            vdbrad::RadiosityOptions o;
            o.directions = 300;
            o.tolerance = 0.0;
            o.maxIterations = sweeps;
            o.update = vdbrad::UpdateScheme::Jacobi;
            vdbrad::RadiositySolver solver(scene, o);
            solver.iterate();   // the first sweep also measures hit weights: not timed
            const auto t0 = Clock::now();
            for (int s = 1; s < sweeps; ++s) solver.iterate();
            seconds[k] = since(t0) / (sweeps - 1);
            denormals = countDenormals(solver.grey().data(), scene.size());
            n = scene.size();
        }
        char what[64];
        std::snprintf(what, sizeof what, "surface: half-lit furnace 64, E 1e-37");
        std::printf("%-44s %10.4f %10.4f %7.2fx %7zu/%zu\n", what, seconds[0], seconds[1],
            seconds[1] / seconds[0], denormals, n);
    }
    {
        // Absorbing slab (omega0 0.5, optical depth 3 per voxel): the diffuse light falls by
        // ~e^-3 per layer, so with F0 = 1e-30 most layers hold denormal radiance.
        const int sweeps = 6;
        double seconds[2];
        size_t denormals = 0, n = 0;
        for (int k = 0; k < 2; ++k) {
            openvdb::FloatGrid::Ptr density = openvdb::FloatGrid::create(0.f);
            density->setName("density");
            density->setTransform(openvdb::math::Transform::createLinearTransform(1.0));
            density->setGridClass(openvdb::GRID_FOG_VOLUME);
            density->tree().fill(openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(15, 39, 15)),
                3.f, true);
            density->tree().voxelizeActiveTiles();
            vdbrad::CloudOptions co;
            co.defaultAlbedo = 0.5f;
            const vdbrad::Cloud cloud = vdbrad::buildCloud({density}, co);
            vdbrad::CloudTransferOptions o;
            o.periodic = true;
            o.directions = 300;
            o.tolerance = 0.0;
            o.irradiance = k ? 1e-30 : 1.0;
            vdbrad::CloudTransfer transfer(cloud, o);
            transfer.iterate();
            const auto t0 = Clock::now();
            for (int s = 1; s < sweeps; ++s) transfer.iterate();
            seconds[k] = since(t0) / (sweeps - 1);
            const std::vector<float> J = transfer.meanIntensity();
            denormals = countDenormals(J.data(), J.size());
            n = J.size();
        }
        std::printf("%-44s %10.4f %10.4f %7.2fx %7zu/%zu\n",
            "cloud: absorbing slab 16x40x16, F0 1e-30", seconds[0], seconds[1],
            seconds[1] / seconds[0], denormals, n);
    }
    std::fflush(stdout);
}

// Part 3: a furnace box of >= 1e7 surface voxels.
void
bigScene(int res, int directions)
{
    std::printf("\n3. big scene: furnace box res %d, rho 0.9, Anderson, %d directions asked\n",
        res, directions);
    auto t0 = Clock::now();
    const vdbrad::Scene scene = furnace(res, 0.9f, 1.f, false);
    const double build = since(t0);
    vdbrad::RadiosityOptions o;
    o.directions = directions;
    o.tolerance = 1e-6;
    o.maxIterations = 100;
    o.accelerate = vdbrad::Acceleration::Anderson;
    t0 = Clock::now();
    vdbrad::RadiositySolver solver(scene, o);
    const double setup = since(t0);
    t0 = Clock::now();
    solver.solve();
    const double solve = since(t0);
    const double exact = 1.0 / (1.0 - double(0.9f));
    double error = 0.0, mean = 0.0;
    for (float b : solver.grey()) {
        const double e = std::abs(double(b) - exact) / exact;
        error = std::max(error, e);
        mean += e / double(scene.size());
    }
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    const double perSweep = solve / solver.iterationCount();
    std::printf("%zu voxels, %zu directions: scene %.1f s, setup %.1f s, %d sweeps in %.1f s "
                "(%.2f s each, %.1f ns per voxel-direction), error max %.2g mean %.2g, "
                "peak RSS %.2f GiB\n",
        scene.size(), solver.directions().size(), build, setup, solver.iterationCount(), solve,
        perSweep, 1e9 * perSweep / (double(scene.size()) * double(solver.directions().size())),
        error, mean, double(ru.ru_maxrss) / (1024.0 * 1024.0));
}

// findRegions on furnace boxes: seconds (best of 3 for the block fill, one run of the dense
// fill), what each holds while it runs, and whether both give the same regions.
void
enclosureTimes(const std::vector<int>& resolutions)
{
    std::printf("enclosure: findRegions on furnace boxes, block fill vs dense fill\n");
    std::printf("%6s %8s %11s %9s %-8s %9s %9s %8s %10s %10s %5s\n", "res", "voxels", "box cells",
        "blocks", "lines", "blocks s", "dense s", "ratio", "blocks MiB", "dense MiB", "same");
    for (const int signedRes : resolutions) {
        const int res = std::abs(signedRes);
        const vdbrad::Scene scene = furnace(res, 0.5f, 1.f, false);
        const openvdb::Coord dim = scene.voxels().bbox().expandBy(2).dim();
        const double cells = double(dim.x()) * double(dim.y()) * double(dim.z());
        const uint64_t blocks = vdbrad::regionBlocks(scene.voxels());
        // Dense: two bits per cell (walls and visited), a front cell per voxel.
        const double denseBytes = cells / 4.0 + 8.0 * double(scene.size());
        for (const vdbrad::LineType lines : {vdbrad::LineType::Naive, vdbrad::LineType::Standard}) {
            double sparse = 1e300;
            vdbrad::Regions regions;
            for (int k = 0; k < 3; ++k) {
                const auto t0 = Clock::now();
                regions = vdbrad::findRegions(scene.voxels(), scene.normals(), lines,
                    uint64_t(1) << 31);
                sparse = std::min(sparse, since(t0));
            }
            char dense[16] = "-", ratio[16] = "-", same[8] = "-";
            if (signedRes > 0) {
                const auto t0 = Clock::now();
                const vdbrad::Regions reference = vdbrad::test::denseRegions(scene.voxels(),
                    scene.normals(), lines, uint64_t(1) << 40);
                const double seconds = since(t0);
                std::snprintf(dense, sizeof dense, "%.3f", seconds);
                std::snprintf(ratio, sizeof ratio, "%.0fx", seconds / sparse);
                const bool equal = reference.region == regions.region
                    && reference.cavities == regions.cavities
                    && reference.analysed == regions.analysed;
                std::snprintf(same, sizeof same, "%s", equal ? "yes" : "NO");
            }
            std::printf(
                "%6d %8zu %11.3g %9llu %-8s %9.3f %9s %8s %10.1f %10.1f %5s  (%u cavities)\n", res, scene.size(), cells, (unsigned long long)blocks,
                lines == vdbrad::LineType::Naive ? "naive" : "standard", sparse, dense, ratio,
                double(vdbrad::regionsBytes(scene.voxels())) / (1 << 20), denseBytes / (1 << 20),
                same, regions.cavities);
            std::fflush(stdout);
        }
    }
}

} // namespace

int
main(int argc, char** argv)
{
    openvdb::initialize();
    if (argc > 1 && std::string(argv[1]) == "enclosure") {
        std::vector<int> resolutions;
        for (int i = 2; i < argc; ++i) resolutions.push_back(std::atoi(argv[i]));
        if (resolutions.empty()) resolutions = {256, 512};
        enclosureTimes(resolutions);
        return 0;
    }
    const int bigRes = argc > 1 ? std::atoi(argv[1]) : 1300;
    const int bigDirections = argc > 2 ? std::atoi(argv[2]) : 50;
    albedoTable();
    denormalTimes();
    if (bigRes > 0) bigScene(bigRes, bigDirections);
    return 0;
}
