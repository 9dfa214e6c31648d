// Glossy surfaces (thesis ch. 5): control points against spherical harmonics, and glossy against
// diffuse solves.
//
//   bench_glossy fit           lobe fit error against the number of values (control points:
//                              12..2562; harmonics: (L+1)^2 for L = 2..24), least squares
//   bench_glossy ops           time per operation (query, splat, scale, add, rotate) of one
//                              distribution, both representations at matched sizes
//   bench_glossy solve RES D   the glossy Cornell box (samples/meshes/glossy_cornell.obj) at RES
//                              voxels, D directions: diffuse, diffuse with the blocks' Ks in
//                              their albedo (same energy), glossy blocks, everything glossy,
//                              and both glossy scenes again on harmonics of order 8 (81
//                              coefficients, --harmonics 8): seconds, iterations, the solver's
//                              memory estimate, and the harmonic solves' glossy exitances
//                              against the control points' (mean |difference| / mean)
//
// Errors are relative to the lobe's peak over a 20,480-direction validation set of the upper
// hemisphere (never a fit sample). Times: best of 3 (BenchTiming.h).
#include "BenchTiming.h"

#include "vdbrad/core/Constants.h"
#include "vdbrad/glossy/Brdf.h"
#include "vdbrad/glossy/ControlPoints.h"
#include "vdbrad/glossy/GlossySurfaces.h"
#include "vdbrad/glossy/SphericalFit.h"
#include "vdbrad/glossy/SphericalHarmonics.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/vdbrad.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <vector>

using namespace vdbrad;
using openvdb::Vec3d;

namespace {


struct Lobe
{
    const char* name;
    BrdfModel model;
    double roughness;
};

// The outgoing lobe pi f(wi, .) for light 30 degrees off the normal.
std::vector<double>
targets(const Brdf& brdf, const std::vector<Vec3d>& dirs)
{
    const Vec3d wi(std::sin(kPi / 6), 0.0, std::cos(kPi / 6));
    std::vector<double> y(dirs.size());
    for (size_t k = 0; k < dirs.size(); ++k) y[k] = kPi * brdf.value(wi, dirs[k]);
    return y;
}

// Directions of the upper hemisphere with solid angles: a control-point quadrature.
void
hemisphere(int order, int cuts, std::vector<Vec3d>& dirs, std::vector<double>& weights)
{
    const ControlPoints grid(order);
    for (const ControlPoints::Sample& s : grid.quadrature(cuts)) {
        if (s.direction.z() <= 0.0) continue;
        dirs.push_back(s.direction);
        weights.push_back(s.solidAngle);
    }
}

int
runFit()
{
    const Lobe lobes[] = {{"phong r0.3 (N 245)", BrdfModel::Phong, 0.3},
        {"phong r0.5 (N 30)", BrdfModel::Phong, 0.5}, {"phong r0.7 (N 6.3)", BrdfModel::Phong, 0.7},
        {"ggx r0.3", BrdfModel::Ggx, 0.3}, {"ggx r0.5", BrdfModel::Ggx, 0.5},
        {"ggx r0.7", BrdfModel::Ggx, 0.7}};
    // Fit samples: 40,960 per sphere; validation: another grid's 20,480 upper directions.
    std::vector<Vec3d> fitDirs, valDirs;
    std::vector<double> fitW, valW;
    hemisphere(4, 4, fitDirs, fitW);
    hemisphere(3, 6, valDirs, valW);
    std::printf("# fit of pi lobe(wi, .) (wi 30 deg off the normal) by least squares; errors on "
                "%zu validation directions, relative to the lobe's peak\n", valDirs.size());
    std::printf("%-22s %-18s %7s %10s %10s %10s\n", "lobe", "representation", "values",
        "rms", "max", "fit s");
    for (const Lobe& lobe : lobes) {
        const Brdf brdf(lobe.model, lobe.roughness);
        const std::vector<double> yFit = targets(brdf, fitDirs), yVal = targets(brdf, valDirs);
        double peak = 0.0;
        for (const double y : yVal) peak = std::max(peak, y);
        auto report = [&](const char* kind, size_t values, const std::vector<double>& got,
                          double seconds) {
            double sq = 0.0, worst = 0.0, w = 0.0;
            for (size_t k = 0; k < got.size(); ++k) {
                const double e = std::abs(got[k] - yVal[k]);
                sq += valW[k] * e * e;
                w += valW[k];
                worst = std::max(worst, e);
            }
            std::printf("%-22s %-18s %7zu %10.4f %10.4f %10.4f\n", lobe.name, kind, values,
                std::sqrt(sq / w) / peak, worst / peak, seconds);
        };
        for (int order = 0; order <= 4; ++order) {
            const ControlPoints cp(order);
            FitProblem problem;
            problem.columns = cp.size();
            for (size_t k = 0; k < fitDirs.size(); ++k) {
                const ControlPoints::Weights w = cp.weights(fitDirs[k]);
                problem.addRow(w.index.data(), w.weight.data(), 3, yFit[k], fitW[k]);
            }
            FitOptions o;
            o.ridge = 1e-12;
            FitResult fit;
            const double s = bench::timeIt([&] { fit = fitControlValues(problem, o); }, 1);
            std::vector<double> got(valDirs.size());
            for (size_t k = 0; k < valDirs.size(); ++k) got[k] = cp.evaluate(fit.x.data(), valDirs[k]);
            report("control points", cp.size(), got, s);
        }
        for (const int L : {2, 5, 8, 12, 16, 24}) {
            const SphericalHarmonics sh(L);
            // Samples weighted by their solid angle: scale rows by sqrt(w).
            std::vector<double> y(yFit.size());
            std::vector<Vec3d> dirs = fitDirs;
            std::vector<double> c;
            const double s = bench::timeIt([&] {
                FitProblem problem;
                problem.columns = sh.size();
                std::vector<uint32_t> cols(sh.size());
                for (size_t j = 0; j < cols.size(); ++j) cols[j] = uint32_t(j);
                std::vector<double> basis(sh.size());
                for (size_t k = 0; k < fitDirs.size(); ++k) {
                    sh.basis(fitDirs[k], basis.data());
                    problem.addRow(cols.data(), basis.data(), cols.size(), yFit[k], fitW[k]);
                }
                FitOptions o;
                o.ridge = 1e-12;
                c = fitControlValues(problem, o).x;
            }, 1);
            std::vector<double> got(valDirs.size());
            for (size_t k = 0; k < valDirs.size(); ++k) got[k] = sh.evaluate(c.data(), valDirs[k]);
            char kind[32];
            std::snprintf(kind, sizeof kind, "harmonics L=%d", L);
            report(kind, sh.size(), got, s);
        }
    }
    return 0;
}

int
runOps()
{
    std::printf("# time per operation on one distribution (ns), best of 3 over 200,000 calls; "
                "rotation: applying a precomputed map or block matrices\n");
    std::printf("%-7s %-16s %12s %12s %12s %12s %12s %12s\n", "values", "representation",
        "query", "query(w)", "splat(w)", "scale", "add", "rotate");
    std::mt19937_64 rng(1);
    std::normal_distribution<double> g;
    std::vector<Vec3d> dirs(4096);
    for (Vec3d& d : dirs) d = Vec3d(g(rng), g(rng), g(rng)).unit();
    const int calls = 200000;
    volatile double sink = 0.0;
    const openvdb::math::Mat3d R = ControlPoints::frame(Vec3d(0.3, -0.4, 0.866).unit());
    const std::pair<int, int> sizes[] = {{1, 5}, {2, 12}, {3, 24}};   // CP order, SH order
    for (const auto& [order, L] : sizes) {
        const ControlPoints cp(order);
        const size_t P = cp.size();
        std::vector<double> x(P, 1.0), y(P, 0.5);
        std::vector<ControlPoints::Weights> w(dirs.size());
        for (size_t k = 0; k < dirs.size(); ++k) w[k] = cp.weights(dirs[k]);
        const ControlPoints::Map map = cp.rotation(R, ControlPoints::RotationKind::Resampled);
        auto ns = [&](auto&& f) { return 1e9 * bench::timeIt(f) / calls; };
        const double query = ns([&] {
            double s = 0.0;
            for (int c = 0; c < calls; ++c) s += cp.evaluate(x.data(), dirs[size_t(c) & 4095]);
            sink = s;
        });
        const double queryW = ns([&] {
            double s = 0.0;
            for (int c = 0; c < calls; ++c) {
                const ControlPoints::Weights& u = w[size_t(c) & 4095];
                s += u.weight[0] * x[u.index[0]] + u.weight[1] * x[u.index[1]]
                    + u.weight[2] * x[u.index[2]];
            }
            sink = s;
        });
        const double splat = ns([&] {
            for (int c = 0; c < calls; ++c) {
                const ControlPoints::Weights& u = w[size_t(c) & 4095];
                for (int j = 0; j < 3; ++j) y[u.index[j]] += 0.1 * u.weight[j];
            }
        });
        const double scale = ns([&] {
            for (int c = 0; c < calls / 64; ++c) for (double& v : y) v *= 0.999;
        }) * 64;
        const double add = ns([&] {
            for (int c = 0; c < calls / 64; ++c) for (size_t i = 0; i < P; ++i) y[i] += x[i];
        }) * 64;
        const double rotate = ns([&] {
            for (int c = 0; c < calls / 64; ++c) map.apply(x.data(), y.data());
        }) * 64;
        std::printf("%-7zu %-16s %12.1f %12.1f %12.1f %12.1f %12.1f %12.1f\n", P,
            "control points", query, queryW, splat, scale, add, rotate);

        const SphericalHarmonics sh(L);
        const size_t M = sh.size();
        std::vector<double> a(M, 0.1), b(M, 0.0);
        std::vector<std::vector<double>> basis(dirs.size(), std::vector<double>(M));
        for (size_t k = 0; k < dirs.size(); ++k) sh.basis(dirs[k], basis[k].data());
        const SphericalHarmonics::Rotation rot = sh.rotation(R);
        const int few = calls / 16;
        const double shQuery = 1e9 * bench::timeIt([&] {
            double s = 0.0;
            for (int c = 0; c < few; ++c) s += sh.evaluate(a.data(), dirs[size_t(c) & 4095]);
            sink = s;
        }) / few;
        const double shQueryW = ns([&] {
            double s = 0.0;
            for (int c = 0; c < calls; ++c) {
                const std::vector<double>& y0 = basis[size_t(c) & 4095];
                for (size_t j = 0; j < M; ++j) s += a[j] * y0[j];
            }
            sink = s;
        });
        const double shSplat = ns([&] {
            for (int c = 0; c < calls; ++c) {
                const std::vector<double>& y0 = basis[size_t(c) & 4095];
                for (size_t j = 0; j < M; ++j) b[j] += 0.1 * y0[j];
            }
        });
        const double shScale = ns([&] {
            for (int c = 0; c < calls / 64; ++c) SphericalHarmonics::scale(0.999, b.data(), M);
        }) * 64;
        const double shAdd = ns([&] {
            for (int c = 0; c < calls / 64; ++c) SphericalHarmonics::add(a.data(), b.data(), M);
        }) * 64;
        const double shRotate = ns([&] {
            for (int c = 0; c < calls / 64; ++c) sh.rotate(rot, a.data(), b.data());
        }) * 64;
        char kind[32];
        std::snprintf(kind, sizeof kind, "harmonics L=%d", L);
        std::printf("%-7zu %-16s %12.1f %12.1f %12.1f %12.1f %12.1f %12.1f\n", M, kind, shQuery,
            shQueryW, shSplat, shScale, shAdd, shRotate);
    }
    (void)sink;
    return 0;
}

int
runSolve(int res, int directions)
{
    const std::string mesh = std::string(VDBRAD_SOURCE_DIR) + "/samples/meshes/glossy_cornell.obj";
    const TriangleMesh m = readMesh(mesh);
    std::printf("# glossy Cornell box, res %d, %d directions, in-place, tolerance 1e-4, "
                "exact direct light; %d threads\n", res, directions,
        tbb::this_task_arena::max_concurrency());
    std::printf("%-26s %9s %9s %6s %9s %9s %11s %7s\n", "scene", "voxels", "glossy", "iters",
        "wall s", "s/iter", "memory MB", "ratio");
    double base = 0.0;
    size_t baseMemory = 0;
    double sameAlbedo = 0.0;
    // Modes 4 and 5: modes 2 and 3 on harmonics, against their control-point solves' times
    // and exitances.
    double pointsWall[2] = {0.0, 0.0};
    std::vector<float> pointsGrey[2];
    for (int mode = 0; mode < 6; ++mode) {
        const bool harmonics = mode >= 4;
        const int kind = harmonics ? mode - 2 : mode;
        VoxelizeOptions vo;
        vo.resolution = res;
        vo.specular = kind == 1 || kind == 2;
        openvdb::GridPtrVec grids = voxelizeMesh(m, vo);
        if (kind == 1) {
            // The blocks' Ks folded into their diffuse albedo: the same energy in every bounce,
            // so the same number of iterations as the glossy solve needs (its baseline).
            auto albedo = openvdb::ConstPtrCast<openvdb::Vec3SGrid>(
                openvdb::gridConstPtrCast<openvdb::Vec3SGrid>(findGrid(grids, "albedo")));
            auto ks = openvdb::gridConstPtrCast<openvdb::Vec3SGrid>(findGrid(grids, "specular"));
            if (!albedo || !ks) {
                std::fprintf(stderr, "bench_glossy: the voxelizer's albedo/specular are not RGB\n");
                return 1;
            }
            auto acc = albedo->getAccessor();
            for (auto it = ks->cbeginValueOn(); it; ++it) {
                acc.setValue(it.getCoord(), acc.getValue(it.getCoord()) + *it);
            }
            grids.erase(std::remove_if(grids.begin(), grids.end(), [](const auto& g) {
                return g->getName() == "specular" || g->getName() == "roughness";
            }), grids.end());
        }
        Scene scene = buildScene(grids);
        if (kind == 3) {
            // Everything glossy: a lobe of 0.2 on top of each wall's albedo (whites: 0.93).
            scene.setGloss(Attribute(0.2f), Attribute(0.5f));
        }
        size_t glossy = 0;
        for (size_t i = 0; i < scene.size(); ++i) glossy += scene.specular().grey(i) > 0.f;
        RadiosityOptions o;
        o.directions = directions;
        o.tolerance = 1e-4;
        o.direct = DirectMode::Exact;
        if (harmonics) {
            o.glossy.basis = GlossyBasis::Harmonics;
            o.glossy.harmonicOrder = 8;
        }
        const size_t memory = RadiositySolver::memoryEstimate(scene, o,
            tbb::this_task_arena::max_concurrency());
        bench::Spent took;
        const auto solver = bench::solved<RadiositySolver>(took, scene, o);
        const double perIteration = took.wall / solver->iterationCount();
        if (mode == 0) { base = took.wall; baseMemory = memory; }
        if (mode == 1) sameAlbedo = took.wall;
        const char* names[] = {"diffuse", "diffuse, blocks Kd + Ks", "glossy blocks (MTL Ks/Ns)",
            "everything glossy", "glossy blocks, SH L=8", "everything glossy, SH L=8"};
        std::printf("%-26s %9zu %9zu %6d %9.2f %9.3f %11.1f %7.2f\n", names[mode], scene.size(),
            glossy, solver->iterationCount(), took.wall, perIteration, memory / 1048576.0,
            took.wall / base);
        if (solver->glossy()) {
            char same[128] = "";
            if (mode == 2) {
                std::snprintf(same, sizeof same, "; %.2fx the diffuse solve of Kd + Ks",
                    took.wall / sameAlbedo);
            }
            // The radiosity's channels' mean per voxel.
            auto mean = [&] {
                std::vector<float> v(scene.size());
                const std::vector<openvdb::Vec3f> rgb = solver->rgb();
                for (size_t i = 0; i < v.size(); ++i) v[i] = (rgb[i][0] + rgb[i][1] + rgb[i][2]) / 3.f;
                return v;
            };
            if (kind >= 2 && !harmonics) {
                pointsWall[kind - 2] = took.wall;
                pointsGrey[kind - 2] = mean();
            }
            if (harmonics) {
                // The glossy voxels' radiosity against the control points' solve of the same
                // scene: where the two representations disagree.
                const std::vector<float>& a = pointsGrey[kind - 2];
                const std::vector<float> b = mean();
                double diff = 0.0, sum = 0.0;
                for (size_t i = 0; i < scene.size() && i < a.size(); ++i) {
                    if (scene.specular().grey(i) <= 0.f) continue;
                    diff += std::abs(double(b[i]) - a[i]);
                    sum += a[i];
                }
                std::snprintf(same, sizeof same, "; %.2fx the control points' time, glossy "
                    "radiosity %.2f %% from theirs", took.wall / pointsWall[kind - 2],
                    100.0 * diff / sum);
            }
            std::printf("    %s; setup %.2f s; memory %.2fx diffuse%s\n",
                solver->glossy()->describe().c_str(), solver->glossy()->setupSeconds(),
                double(memory) / double(baseMemory), same);
        }
    }
    return 0;
}

} // namespace

int
main(int argc, char** argv)
{
    openvdb::initialize();
    const std::string mode = argc > 1 ? argv[1] : "";
    if (mode == "fit") return runFit();
    if (mode == "ops") return runOps();
    if (mode == "solve") {
        return runSolve(argc > 2 ? std::atoi(argv[2]) : 64, argc > 3 ? std::atoi(argv[3]) : 300);
    }
    std::fprintf(stderr, "usage: bench_glossy fit | ops | solve [RES [DIRECTIONS]]\n");
    return 2;
}
