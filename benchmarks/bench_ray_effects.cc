// Ray effects of the reflected light (issue 23, part 2): the ways of spreading a bounce over more
// directions than one fixed set, each at its own cost, on a scene file. Writes the solved file for
// `vdbrad render`; benchmarks/ray_effects.sh renders every variant and measures its error.
//
//   bench_ray_effects IN.vdb OUT.vdb ITERATIONS fixed COUNT
//   bench_ray_effects IN.vdb OUT.vdb ITERATIONS alternate COUNT COUNT ...
//       iteration k sweeps the set of the (k mod m)-th count (the other radii of the discrete
//       sphere: its 48 signed axis permutations map a set onto itself, so they change nothing)
//   bench_ray_effects IN.vdb OUT.vdb ITERATIONS average COUNT COUNT ...
//       one whole solve per set, their radiosities averaged (m times the cost)
//   bench_ray_effects IN.vdb OUT.vdb ITERATIONS smooth RADIUS COUNT
//       a fixed set, then the reflected part B - E - rho D averaged over the voxels of the same
//       wall (normals within 18 degrees) in the (2 RADIUS + 1)^3 block around each voxel
//
// Jacobi updates (each iterate a function of the previous one alone, so a set can hand over to
// another), no visibility cache (each iteration sweeps), exact direct light. Prints the wall
// time of the solve (direct light included, once per set where each set has its own solver) and
// of the smoothing.
#include "vdbrad/scene/OutputGrids.h"
#include "vdbrad/scene/SurfacePlanes.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/vdbrad.h"

#include <openvdb/openvdb.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

namespace {

using Clock = std::chrono::steady_clock;
using openvdb::Vec3f;

double
since(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

std::unique_ptr<vdbrad::RadiositySolver>
makeSolver(const vdbrad::Scene& scene, int count)
{
    vdbrad::RadiosityOptions o;
    o.directions = count;
    o.update = vdbrad::UpdateScheme::Jacobi;
    o.maxIterations = 1 << 20;
    o.tolerance = 0.0;
    o.visibilityCache = 0;
    o.direct = vdbrad::DirectMode::Exact;
    return std::make_unique<vdbrad::RadiositySolver>(scene, o);
}

// B with its reflected part averaged over the same wall's voxels within `radius`.
std::vector<Vec3f>
smoothReflected(const vdbrad::Scene& scene, const vdbrad::RadiositySolver& solver, int radius)
{
    const std::vector<Vec3f>& D = solver.directLight().irradiance;
    std::vector<Vec3f> B = solver.rgb(), R(B.size());
    for (size_t i = 0; i < B.size(); ++i) {
        R[i] = B[i] - scene.emission().rgb(i) - scene.albedo().rgb(i) * D[i];
    }
    const vdbrad::VoxelIndex& voxels = scene.voxels();
    for (size_t i = 0; i < B.size(); ++i) {
        openvdb::Vec3d sum(0.0);
        int n = 0;
        for (int dx = -radius; dx <= radius; ++dx) {
            for (int dy = -radius; dy <= radius; ++dy) {
                for (int dz = -radius; dz <= radius; ++dz) {
                    const int32_t j = voxels.find(voxels.coord(i).offsetBy(dx, dy, dz));
                    if (j < 0 || scene.normal(size_t(j)).dot(scene.normal(i)) < vdbrad::kSameWall) continue;
                    sum += openvdb::Vec3d(R[size_t(j)]);
                    ++n;
                }
            }
        }
        B[i] += Vec3f(sum / double(n)) - R[i];   // n >= 1: the voxel itself
    }
    return B;
}

} // namespace

int
main(int argc, char** argv)
{
    if (argc < 6) {
        std::fprintf(stderr, "usage: bench_ray_effects IN.vdb OUT.vdb ITERATIONS "
            "fixed|alternate|average|smooth [RADIUS] COUNT ...\n");
        return 2;
    }
    openvdb::initialize();
    const std::string mode = argv[4];
    const int iterations = std::atoi(argv[3]);
    int radius = 0, first = 5;
    if (mode == "smooth") radius = std::atoi(argv[first++]);
    std::vector<int> counts;
    for (int a = first; a < argc; ++a) counts.push_back(std::atoi(argv[a]));

    openvdb::io::File in(argv[1]);
    in.open(false);
    const openvdb::GridPtrVec grids = *in.getGrids();
    in.close();
    const vdbrad::Scene scene = vdbrad::buildScene(grids);
    if (!scene.isRgb()) {
        std::fprintf(stderr, "bench_ray_effects: an RGB scene is expected (the Cornell box)\n");
        return 2;
    }

    const Clock::time_point t0 = Clock::now();
    std::vector<std::unique_ptr<vdbrad::RadiositySolver>> solvers;
    for (const int c : counts) solvers.push_back(makeSolver(scene, c));
    std::vector<Vec3f> B(scene.size(), Vec3f(0.f));
    double smoothSeconds = 0.0;
    if (mode == "average") {
        for (auto& s : solvers) {
            for (int k = 0; k < iterations; ++k) s->iterate();
            for (size_t i = 0; i < B.size(); ++i) B[i] += s->rgb()[i] / float(solvers.size());
        }
    } else {
        size_t last = 0;
        for (int k = 0; k < iterations; ++k) {
            const size_t j = size_t(k) % solvers.size();
            if (j != last) solvers[j]->setRadiosity(solvers[last]->rgb());
            solvers[j]->iterate();
            last = j;
        }
        B = solvers[last]->rgb();
        if (mode == "smooth") {
            const Clock::time_point t1 = Clock::now();
            B = smoothReflected(scene, *solvers[last], radius);
            smoothSeconds = since(t1);
        }
    }
    std::printf("%s", mode.c_str());
    for (auto& s : solvers) std::printf(" %zu", s->directions().size());
    std::printf(" directions, %d iterations: %.2f s (direct light %.2f s per set)",
        iterations, since(t0), solvers[0]->directLight().seconds);
    if (mode == "smooth") std::printf(", smoothing radius %d %.3f s", radius, smoothSeconds);
    std::printf("\n");

    openvdb::GridPtrVec out = grids;
    out.push_back(vdbrad::makeRadiosityGrid(scene, B, vdbrad::SolveStats()));
    openvdb::io::File file(argv[2]);
    file.write(out);
    file.close();
    return 0;
}
