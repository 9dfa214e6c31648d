// The speed/accuracy trade, measured against exact references; one CSV row per run.
//
//   build/benchmarks/bench_trade [out.csv [study...]]   (default: standard output, all studies)
//
// study "disk": the emitting disk under the albedo-1 receiver, whose irradiance is known at
//   every receiver point (grids::diskIrradiance, Howell B-13); two iterations are exact for it
//   (the disk does not reflect), with the direct light sent through the sweeps (--direct sweep:
//   exact direct light, the default, gives it to rounding: bench_direct). Knobs: resolution
//   (32-512) x direction count x line type. Errors over
//   the receiver voxels within 0.5 of the axis (irradiance >= ~0.1): the mean and the max of
//   |B - exact| / exact, and the on-axis error of bench_accuracy.
// study "cornell": the RGB Cornell box against the two-pass Monte Carlo reference on the same
//   voxels (256 stored rays per voxel converged to 1e-6, then a final gather of 16,384 rays at
//   4096 voxels spread over the index order): res 32-512 x directions x line type, solves to
//   tolerance 1e-5. Errors over those voxels: mean |dB| / mean B and max |dB| / max B over
//   voxels and channels; the reference's own mean standard error / mean B is printed as
//   axis_err (its noise floor).
// study "cornell-split": res 64, naive lines, 967-9957 directions: the same errors per kind of
//   voxel (one row each, the scene column naming it and axis_err holding the signed mean error):
//   "axis-aligned" normals, "tilted" ones, and "shadowed": voxels more than 2% of whose stored
//   rays hit the back of a neighbouring patch (staircase steps of the rotated boxes; the Monte
//   Carlo's plane patches shade each other there, the sweeps' rule does not).
// study "iterations": the RGB Cornell box at res 48 with 300 directions, k iterations of each
//   update scheme against a solve converged to 1e-7 with the same lines and directions (so only
//   the iteration knob differs): mean |dB| / mean B and max |dB| / max B.
// seconds: construction + solve, all cores. peak_mb: the process's peak resident set during the
//   run (reset before it through /proc/self/clear_refs; the scene itself included).
#include "grids/CanonicalGrids.h"
#include "vdbrad/reference/MonteCarloSolver.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/vdbrad.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <memory>
#include <tuple>
#include <utility>
#include <string>
#include <vector>

namespace {

void
resetPeakMemory()
{
    std::ofstream("/proc/self/clear_refs") << "5";
}

double
peakMegabytes()
{
    std::ifstream in("/proc/self/status");
    for (std::string line; std::getline(in, line);) {
        if (line.rfind("VmHWM:", 0) == 0) return std::stod(line.substr(6)) / 1024.0;
    }
    return 0.0;
}

// A solver constructed and run to its options' end, with its wall time and the peak resident set.
struct Run
{
    std::unique_ptr<vdbrad::RadiositySolver> solver;
    double seconds = 0.0, peakMb = 0.0;
};

Run
run(const vdbrad::Scene& scene, const vdbrad::RadiosityOptions& o)
{
    Run r;
    resetPeakMemory();
    const auto t0 = std::chrono::steady_clock::now();
    r.solver.reset(new vdbrad::RadiositySolver(scene, o));
    r.solver->solve();
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    r.peakMb = peakMegabytes();
    return r;
}

// Sum and max over voxels and channels of |a - b|.
std::pair<double, double>
difference(const std::vector<openvdb::Vec3f>& a, const std::vector<openvdb::Vec3f>& b)
{
    double sum = 0.0, worst = 0.0;
    for (size_t i = 0; i < a.size(); ++i) {
        for (int c = 0; c < 3; ++c) {
            const double d = std::abs(double(a[i][c]) - double(b[i][c]));
            sum += d;
            worst = std::max(worst, d);
        }
    }
    return {sum, worst};
}

// Sum and max over voxels and channels of a.
std::pair<double, double>
magnitude(const std::vector<openvdb::Vec3f>& a)
{
    return difference(a, std::vector<openvdb::Vec3f>(a.size(), openvdb::Vec3f(0.f)));
}

// The two-pass Monte Carlo reference at @a probes: values, mean standard error / mean B, and
// per probe whether more than 2% of its stored rays hit a patch's back.
struct Reference
{
    std::vector<openvdb::Vec3f> B;
    double noise = 0.0;
    std::vector<char> shadowed;
};

Reference
cornellReference(const vdbrad::Scene& scene, const std::vector<size_t>& probes)
{
    vdbrad::MonteCarloOptions mo;
    mo.samples = 256;
    mo.tolerance = 1e-6;
    vdbrad::MonteCarloSolver mc(scene, mo);
    mc.solve();
    const vdbrad::MonteCarloGather g = mc.gather(probes, 16384);
    Reference r;
    r.B = g.rgb;
    r.noise = magnitude(g.rgbError).first / magnitude(g.rgb).first;
    for (size_t i : probes) {
        int back = 0;
        for (int s = 0; s < mo.samples; ++s) back += mc.hit(i, s) == mc.kBack ? 1 : 0;
        r.shadowed.push_back(back > mo.samples / 50 ? 1 : 0);
    }
    return r;
}

// @a count voxel indices spread evenly over the index order (the whole scene).
std::vector<size_t>
spread(size_t n, size_t count)
{
    count = std::min(n, count);
    std::vector<size_t> probes;
    for (size_t k = 0; k < count; ++k) probes.push_back(k * n / count);
    return probes;
}

const char* name(vdbrad::LineType t) { return t == vdbrad::LineType::Naive ? "naive" : "standard"; }
const char*
name(vdbrad::UpdateScheme u)
{
    return u == vdbrad::UpdateScheme::Jacobi ? "jacobi"
        : u == vdbrad::UpdateScheme::InPlace ? "inplace" : "progressive";
}

} // namespace

int
main(int argc, char** argv)
{
    openvdb::initialize();
    FILE* out = argc > 1 && std::string(argv[1]) != "-" ? std::fopen(argv[1], "w") : stdout;
    if (!out) { std::perror(argv[1]); return 1; }
    const std::vector<std::string> only(argv + std::min(argc, 2), argv + argc);
    auto wanted = [&](const std::string& study) {
        return only.empty() || std::find(only.begin(), only.end(), study) != only.end();
    };
    std::fprintf(out, "study,scene,res,voxels,directions,lines,update,iterations,seconds,peak_mb,"
                      "axis_err,mean_err,max_err\n");

    {
        // Warm-up (thread pool, allocator), so that the first timed run is not an outlier.
        vdbrad::grids::BuildParams p;
        p.res = 32;
        vdbrad::RadiositySolver(vdbrad::buildScene(vdbrad::grids::makeDisk(p))).solve();
    }
    for (int res : {32, 64, 128, 256, 512}) {
        if (!wanted("disk")) break;
        vdbrad::grids::BuildParams p;
        p.res = res;
        const vdbrad::Scene scene = vdbrad::buildScene(vdbrad::grids::makeDisk(p));
        const double vs = scene.voxelSize();
        for (vdbrad::LineType lines : {vdbrad::LineType::Naive, vdbrad::LineType::Standard}) {
            for (int dirs : {50, 100, 300, 1000, 3000, 10000, 20000}) {
                if (res >= 512 && dirs > 10000) continue;   // minutes per point: run by hand
                vdbrad::RadiosityOptions o;
                o.directions = dirs;
                o.maxIterations = 2;
                o.tolerance = 0.0;
                o.lines = lines;
                // The sweeps' own transport: exact direct light (the default) makes it exact.
                o.direct = vdbrad::DirectMode::Sweep;
                const Run r = run(scene, o);
                const vdbrad::RadiositySolver& solver = *r.solver;
                double axisB = 0.0, axisExact = 0.0, sum = 0.0, worst = 0.0;
                size_t count = 0;
                for (size_t i = 0; i < scene.size(); ++i) {
                    const openvdb::Coord c = scene.voxels().coord(i);
                    if (c.y() == 0) continue;   // the disk
                    const double x = (c.x() + 0.5) * vs - 0.5, z = (c.z() + 0.5) * vs - 0.5;
                    const double a = std::sqrt(x * x + z * z);
                    if (a > 0.5) continue;
                    const double exact = vdbrad::grids::diskIrradiance(1.0, 0.25, c.y() * vs, a);
                    const double err = std::abs(solver.grey()[i] - exact) / exact;
                    sum += err;
                    worst = std::max(worst, err);
                    ++count;
                    if (a <= vs) { axisB += solver.grey()[i]; axisExact += exact; }
                }
                std::fprintf(out, "disk,disk,%d,%zu,%zu,%s,jacobi,2,%.4f,%.1f,%.4g,%.4g,%.4g\n",
                    res, scene.size(), solver.directions().size(), name(lines), r.seconds,
                    r.peakMb, std::abs(axisB - axisExact) / axisExact, sum / double(count), worst);
                std::fflush(out);
            }
        }
    }

    for (int res : {32, 64, 128, 256, 512}) {
        if (!wanted("cornell")) break;
        vdbrad::grids::BuildParams p;
        p.res = res;
        const vdbrad::Scene scene = vdbrad::buildScene(vdbrad::grids::makeCornell(p));
        const std::vector<size_t> probes = spread(scene.size(), 4096);
        // Its rays are freed before the sweeps: they must not count in their peaks.
        const Reference ref = cornellReference(scene, probes);
        const std::vector<openvdb::Vec3f>& reference = ref.B;
        const auto [total, maxB] = magnitude(reference);
        for (vdbrad::LineType lines : {vdbrad::LineType::Naive, vdbrad::LineType::Standard}) {
            for (int dirs : {50, 100, 300, 1000, 3000, 10000}) {
                // Minutes per point: run by hand.
                if ((res == 128 && dirs > 3000) || (res == 256 && dirs > 3000)
                    || (res == 512 && dirs > 1000)) continue;
                vdbrad::RadiosityOptions o;
                o.directions = dirs;
                o.lines = lines;
                const Run r = run(scene, o);
                std::vector<openvdb::Vec3f> B(probes.size());
                for (size_t k = 0; k < probes.size(); ++k) B[k] = r.solver->rgb()[probes[k]];
                const auto [diff, worst] = difference(B, reference);
                std::fprintf(out, "cornell,cornell,%d,%zu,%zu,%s,inplace,%d,%.4f,%.1f,%.4g,%.4g,"
                    "%.4g\n", res, scene.size(), r.solver->directions().size(), name(lines),
                    r.solver->iterationCount(), r.seconds, r.peakMb, ref.noise,
                    diff / total, worst / maxB);
                std::fflush(out);
            }
        }
    }

    if (wanted("cornell-split")) {
        vdbrad::grids::BuildParams p;
        p.res = 64;
        const vdbrad::Scene scene = vdbrad::buildScene(vdbrad::grids::makeCornell(p));
        const std::vector<size_t> probes = spread(scene.size(), 4096);
        const Reference ref = cornellReference(scene, probes);
        const char* const kinds[3] = {"axis-aligned", "tilted", "shadowed"};
        std::vector<int> kindOf(probes.size());
        for (size_t k = 0; k < probes.size(); ++k) {
            const openvdb::Vec3f n = scene.normal(probes[k]);
            const int nonzero = (std::abs(n[0]) > 1e-3f) + (std::abs(n[1]) > 1e-3f)
                + (std::abs(n[2]) > 1e-3f);
            kindOf[k] = ref.shadowed[k] ? 2 : nonzero == 1 ? 0 : 1;
        }
        for (int dirs : {1000, 3000, 10000}) {
            vdbrad::RadiosityOptions o;
            o.directions = dirs;
            const Run r = run(scene, o);
            for (int kind = 0; kind < 3; ++kind) {
                std::vector<openvdb::Vec3f> a, b;
                double signedSum = 0.0;
                for (size_t k = 0; k < probes.size(); ++k) {
                    if (kindOf[k] != kind) continue;
                    a.push_back(r.solver->rgb()[probes[k]]);
                    b.push_back(ref.B[k]);
                    for (int c = 0; c < 3; ++c) signedSum += double(a.back()[c]) - b.back()[c];
                }
                const auto [total, maxB] = magnitude(b);
                const auto [diff, worst] = difference(a, b);
                std::fprintf(out, "cornell-split,%s,64,%zu,%zu,naive,inplace,%d,%.4f,%.1f,%.4g,"
                    "%.4g,%.4g\n", kinds[kind], a.size(), r.solver->directions().size(),
                    r.solver->iterationCount(), r.seconds, r.peakMb, signedSum / total,
                    diff / total, worst / maxB);
                std::fflush(out);
            }
        }
    }

    if (!wanted("iterations")) {
        if (out != stdout) std::fclose(out);
        return 0;
    }
    vdbrad::grids::BuildParams p;
    p.res = 48;
    const vdbrad::Scene cornell = vdbrad::buildScene(vdbrad::grids::makeCornell(p));
    vdbrad::RadiosityOptions ref;
    ref.directions = 300;
    ref.maxIterations = 5000;
    ref.tolerance = 1e-7;
    vdbrad::RadiositySolver converged(cornell, ref);
    converged.solve();
    const std::vector<openvdb::Vec3f>& B = converged.rgb();
    const auto [totalB, maxB] = magnitude(B);
    for (vdbrad::UpdateScheme update : {vdbrad::UpdateScheme::Jacobi,
             vdbrad::UpdateScheme::InPlace, vdbrad::UpdateScheme::Progressive}) {
        for (int k : {1, 2, 3, 4, 6, 8, 12, 16, 24, 32, 48, 64}) {
            vdbrad::RadiosityOptions o = ref;
            o.maxIterations = k;
            o.tolerance = 0.0;
            o.update = update;
            const Run r = run(cornell, o);
            const auto [diff, worst] = difference(r.solver->rgb(), B);
            std::fprintf(out, "iterations,cornell,48,%zu,%zu,naive,%s,%d,%.4f,%.1f,,%.4g,%.4g\n",
                cornell.size(), r.solver->directions().size(), name(update), k, r.seconds,
                r.peakMb, diff / totalB, worst / maxB);
            std::fflush(out);
        }
    }
    if (out != stdout) std::fclose(out);
    return 0;
}
