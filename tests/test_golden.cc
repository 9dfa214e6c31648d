// Bit-identity guard: every solver variant, on the canonical scenes, computes exactly the bits it
// computed when tests/golden/solver-bits.txt was written.
//
// Why: refactorings of the shared sweep engine, the iteration helper and the command line must
// not change a single output bit (issue 22); the physics tests' tolerances would let a changed
// summation order through. The hashes (FNV-1a of the output arrays and of the residual history)
// are of this machine's builds: the library is compiled without FP contraction and its vector
// clones give the plain build's bits (docs/journal/2026-11-24-radiosity-solver-speed.md), so they
// do not depend on the CPU or the thread count. A change that is meant to change results (new
// physics) regenerates the file:
//
//     VDBRAD_UPDATE_GOLDEN=1 build/tests/test_golden   (writes both files in tests/golden/)
//
// and says so in its commit message.
#include "vdbrad/cloud/CloudTransfer.h"
#include "vdbrad/cloud/PhaseFunction.h"
#include "vdbrad/core/Checkpoint.h"
#include "vdbrad/reference/MonteCarloSolver.h"
#include "vdbrad/scene/Cloud.h"
#include "vdbrad/surface/RadiositySolver.h"

#include "CanonicalScene.h"
#include "ToolTest.h"

#include <gtest/gtest.h>

#include <openvdb/openvdb.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iomanip>
#include <map>
#include <sstream>

using namespace vdbrad;

namespace {

const char* const kGoldenFile = VDBRAD_SOURCE_DIR "/tests/golden/solver-bits.txt";
const char* const kToolGoldenFile = VDBRAD_SOURCE_DIR "/tests/golden/tool-bits.txt";

template<typename T>
uint64_t
hashOf(const std::vector<T>& v, uint64_t h)
{
    return hashBytes(v.data(), v.size() * sizeof(T), h);
}

std::string
hex(uint64_t h)
{
    std::ostringstream os;
    os << std::hex << std::setw(16) << std::setfill('0') << h;
    return os.str();
}

// One case: a name and how to compute its hash.
struct Case
{
    std::string name;
    std::function<uint64_t()> run;
};

uint64_t
surface(const Scene& scene, RadiosityOptions o)
{
    RadiositySolver solver(scene, o);
    solver.solve();
    uint64_t h = hashOf(solver.residuals(), hashBytes("surface", 7));
    return scene.isRgb() ? hashOf(solver.rgb(), h) : hashOf(solver.grey(), h);
}

uint64_t
cloud(const std::string& builder, int res, CloudTransferOptions o, float albedo = -1.f)
{
    grids::BuildParams p;
    p.res = res;
    p.albedo = albedo;
    const Cloud c = buildCloud(grids::findBuilder(builder)->build(p));
    CloudTransfer transfer(c, o);
    transfer.solve();
    const CloudBudget& b = transfer.budget();
    const double budget[4] = {b.albedo, b.transmittance, b.directTransmittance, b.absorptance};
    uint64_t h = hashOf(transfer.residuals(), hashBytes("cloud", 5));
    h = hashBytes(budget, sizeof budget, h);
    return hashOf(transfer.meanIntensity(), h);
}

std::vector<Case>
cases()
{
    std::vector<Case> all;
    // Surfaces: the Cornell box is RGB, the furnace sphere, disk and plates grey. Few iterations
    // and no tolerance: every variant runs the same count, and the cases stay fast.
    auto base = [] {
        RadiosityOptions o;
        o.directions = 120;
        o.maxIterations = 5;
        o.tolerance = 0.0;
        return o;
    };
    const auto cornell = [] { return test::canonicalScene("cornell", 28); };
    const auto sphere = [](float albedo) { return test::canonicalScene("furnace-sphere", 20,
        albedo); };
    struct Variant
    {
        std::string name;
        std::function<void(RadiosityOptions&)> set;
    };
    const std::vector<Variant> variants = {
        {"inplace", [](RadiosityOptions&) {}},
        {"inplace-cache", [](RadiosityOptions& o) { o.visibilityCache = size_t(1) << 30; }},
        {"inplace-cache-part", [](RadiosityOptions& o) { o.visibilityCache = 40000; }},
        {"jacobi", [](RadiosityOptions& o) { o.update = UpdateScheme::Jacobi; }},
        {"jacobi-cache", [](RadiosityOptions& o) {
            o.update = UpdateScheme::Jacobi;
            o.visibilityCache = size_t(1) << 30;
        }},
        {"progressive", [](RadiosityOptions& o) { o.update = UpdateScheme::Progressive; }},
        {"anderson", [](RadiosityOptions& o) { o.accelerate = Acceleration::Anderson; }},
        {"anderson-cache", [](RadiosityOptions& o) {
            o.accelerate = Acceleration::Anderson;
            o.andersonDepth = 2;
            o.visibilityCache = size_t(1) << 30;
        }},
        {"standard", [](RadiosityOptions& o) { o.lines = LineType::Standard; }},
        {"standard-cache", [](RadiosityOptions& o) {
            o.lines = LineType::Standard;
            o.visibilityCache = size_t(1) << 30;
        }},
        {"double", [](RadiosityOptions& o) { o.precision = Precision::Double; }},
        {"raycast", [](RadiosityOptions& o) { o.visibility = Visibility::RayCast; }},
    };
    for (const Variant& v : variants) {
        all.push_back({"cornell-rgb-" + v.name, [=] {
            RadiosityOptions o = base();
            v.set(o);
            return surface(cornell(), o);
        }});
        all.push_back({"sphere-grey-" + v.name, [=] {
            RadiosityOptions o = base();
            v.set(o);
            return surface(sphere(-1.f), o);
        }});
    }
    // Direct light through the sweeps: the bits of every solve before exact direct light.
    all.push_back({"cornell-rgb-inplace-sweep-direct", [=] {
        RadiosityOptions o = base();
        o.direct = DirectMode::Sweep;
        return surface(cornell(), o);
    }});
    all.push_back({"cornell-rgb-jacobi-sweep-direct", [=] {
        RadiosityOptions o = base();
        o.update = UpdateScheme::Jacobi;
        o.direct = DirectMode::Sweep;
        return surface(cornell(), o);
    }});
    // Exact direct light with 4 shadow rays per voxel.
    all.push_back({"cornell-rgb-exact-4", [=] {
        RadiosityOptions o = base();
        o.direct = DirectMode::Exact;
        o.directSamples = 4;
        return surface(cornell(), o);
    }});
    // Albedo above 0.999: double precision by default, with and without Anderson.
    all.push_back({"sphere-grey-auto-double", [=] {
        RadiosityOptions o = base();
        return surface(sphere(0.9995f), o);
    }});
    all.push_back({"sphere-grey-auto-double-anderson-cache", [=] {
        RadiosityOptions o = base();
        o.accelerate = Acceleration::Anderson;
        o.visibilityCache = size_t(1) << 30;
        return surface(sphere(0.9995f), o);
    }});
    all.push_back({"disk-grey-progressive-cache", [=] {
        RadiosityOptions o = base();
        o.update = UpdateScheme::Progressive;
        o.visibilityCache = size_t(1) << 30;
        return surface(test::canonicalScene("disk", 24), o);
    }});
    all.push_back({"plates-grey-jacobi", [=] {
        RadiosityOptions o = base();
        o.update = UpdateScheme::Jacobi;
        return surface(test::canonicalScene("plates", 24), o);
    }});

    // Clouds.
    // The variants below keep the scheme they were recorded with (constant source, cells'
    // weights, plain sweeps unless named); "defaults" cases follow CloudTransferOptions.
    auto cbase = [] {
        CloudTransferOptions o;
        o.directions = 80;
        o.maxIterations = 6;
        o.tolerance = 0.0;
        o.sunZenith = 30.0;
        o.sunAzimuth = 20.0;
        o.source = VoxelSource::Constant;
        o.harmonicWeights = false;
        o.accelerate = Acceleration::None;
        return o;
    };
    all.push_back({"slab-isotropic-periodic", [=] {
        CloudTransferOptions o = cbase();
        o.periodic = true;
        return cloud("slab", 16, o);
    }});
    all.push_back({"slab-hg-periodic", [=] {
        CloudTransferOptions o = cbase();
        o.periodic = true;
        o.phase = PhaseFunction::henyeyGreenstein(0.85);
        o.phaseOrder = 6;
        return cloud("slab", 16, o);
    }});
    all.push_back({"slab-isotropic-periodic-copies", [=] {
        CloudTransferOptions o = cbase();
        o.periodic = true;
        o.minPeriod = 20;
        return cloud("slab", 8, o, 0.9f);
    }});
    all.push_back({"slab-isotropic-periodic-anderson", [=] {
        CloudTransferOptions o = cbase();
        o.periodic = true;
        o.accelerate = Acceleration::Anderson;
        o.sunZenith = 0.0;
        return cloud("slab", 16, o);
    }});
    all.push_back({"cumulus-isotropic-open", [=] {
        CloudTransferOptions o = cbase();
        return cloud("cumulus", 16, o);
    }});
    all.push_back({"cumulus-hg-open-anderson", [=] {
        CloudTransferOptions o = cbase();
        o.phase = PhaseFunction::henyeyGreenstein(0.6);
        o.phaseOrder = 4;
        o.accelerate = Acceleration::Anderson;
        o.andersonDepth = 4;
        return cloud("cumulus", 16, o, 0.95f);
    }});

    // CloudTransferOptions' defaults, but for a short run of a small direction set and order.
    auto hgDefaults = [](double zenith) {
        CloudTransferOptions o;
        o.periodic = true;
        o.maxIterations = 6;
        o.tolerance = 0.0;
        o.sunZenith = zenith;
        o.phase = PhaseFunction::henyeyGreenstein(0.85);
        o.phaseOrder = 4;
        o.directions = 80;
        return o;
    };
    all.push_back({"slab-hg-periodic-defaults", [=] {
        return cloud("slab", 16, hgDefaults(30.0));
    }});
    all.push_back({"step-cloud-planar-defaults", [=] {
        return cloud("step-cloud", 32, hgDefaults(60.0), 0.99f);
    }});

    // A ground under the slab, and fire (a `flame` grid) in the cumulus, RGB-coloured.
    all.push_back({"slab-isotropic-periodic-ground", [=] {
        CloudTransferOptions o = cbase();
        o.periodic = true;
        o.groundAlbedo = 0.4;
        return cloud("slab", 16, o);
    }});
    all.push_back({"cumulus-fire-open", [=] {
        grids::BuildParams p;
        p.res = 16;
        openvdb::GridPtrVec g = grids::findBuilder("cumulus")->build(p);
        const auto density = openvdb::gridPtrCast<openvdb::FloatGrid>(g.front());
        auto flame = density->deepCopy();
        flame->setName("flame");
        // Fire in the lower half: light that crosses the cloud to reach the top.
        for (auto it = flame->beginValueOn(); it; ++it) it.setValue(it.getCoord().y() < 8 ? 3.f : 0.f);
        g.push_back(flame);
        CloudOptions co;
        co.emissionScale = 0.5f;
        co.emissionColour = openvdb::Vec3f(1.f, 0.5f, 0.25f);
        const Cloud c = buildCloud(g, co);
        CloudTransfer transfer(c, cbase());
        transfer.solve();
        uint64_t h = hashOf(transfer.residuals(), hashBytes("fire", 4));
        return hashOf(transfer.meanIntensity(), h);
    }});

    // Monte Carlo: stored rays, iterations, a final gather.
    all.push_back({"cornell-rgb-montecarlo", [] {
        const Scene scene = test::canonicalScene("cornell", 16);
        MonteCarloOptions o;
        o.samples = 24;
        o.maxIterations = 4;
        o.tolerance = 0.0;
        MonteCarloSolver solver(scene, o);
        solver.solve();
        uint64_t h = hashOf(solver.rgb(), hashBytes("montecarlo", 10));
        solver.finalGather(16);
        h = hashOf(solver.rgb(), h);
        return hashOf(solver.rgbError(), h);
    }});
    return all;
}

std::map<std::string, std::string>
readGolden(const char* path)
{
    std::map<std::string, std::string> golden;
    std::ifstream in(path);
    for (std::string name, hash; in >> name >> hash;) golden[name] = hash;
    return golden;
}

class GoldenTest : public ::testing::Test
{
protected:
    static void SetUpTestSuite() { openvdb::initialize(); }
};

} // namespace

TEST_F(GoldenTest, EverySolverVariantGivesItsRecordedBits)
{
    const std::vector<Case> all = cases();
    const char* update = std::getenv("VDBRAD_UPDATE_GOLDEN");
    if (update && std::string(update) == "1") {
        std::ofstream out(kGoldenFile);
        for (const Case& c : all) out << c.name << " " << hex(c.run()) << "\n";
        ASSERT_TRUE(out.good()) << "cannot write " << kGoldenFile;
        return;
    }
    const std::map<std::string, std::string> golden = readGolden(kGoldenFile);
    ASSERT_EQ(golden.size(), all.size()) << kGoldenFile << " does not list every case";
    for (const Case& c : all) {
        const auto it = golden.find(c.name);
        ASSERT_NE(it, golden.end()) << c.name << " is not in " << kGoldenFile;
        EXPECT_EQ(hex(c.run()), it->second) << c.name << ": the output bits changed";
    }
}

namespace {

// The values of every float or Vec3f grid of a file, in grid name order, hashed.
uint64_t
hashFile(const std::string& path)
{
    openvdb::io::File file(path);
    file.open();
    openvdb::GridPtrVecPtr grids = file.getGrids();
    file.close();
    std::map<std::string, openvdb::GridBase::Ptr> byName;
    for (const auto& g : *grids) byName[g->getName()] = g;
    uint64_t h = hashBytes("file", 4);
    for (const auto& [name, g] : byName) {
        // The solvers' outputs (the inputs pass through unchanged).
        if (name != "radiosity" && name != "mean_intensity" && name != "specular_radiosity"
            && name != "ground_irradiance") continue;
        h = hashBytes(name.data(), name.size(), h);
        if (auto f = openvdb::gridPtrCast<openvdb::FloatGrid>(g)) {
            for (auto it = f->cbeginValueOn(); it; ++it) {
                const float v = *it;
                const openvdb::Coord c = it.getCoord();
                h = hashBytes(&c, sizeof c, h);
                h = hashBytes(&v, sizeof v, h);
            }
        } else if (auto r = openvdb::gridPtrCast<openvdb::Vec3SGrid>(g)) {
            for (auto it = r->cbeginValueOn(); it; ++it) {
                const openvdb::Vec3f v = *it;
                const openvdb::Coord c = it.getCoord();
                h = hashBytes(&c, sizeof c, h);
                h = hashBytes(&v, sizeof v, h);
            }
        }
    }
    return h;
}

class GoldenToolTest : public test::ToolTest {};

} // namespace

// The tool's solves give the recorded bits too (that a killed and resumed solve gives the
// uninterrupted bits: test_cli, ResumingAKilledSolveFromItsCheckpointGivesTheUninterruptedBits).
TEST_F(GoldenToolTest, ToolSolvesGiveTheirRecordedBits)
{
    const std::string glossyMesh = VDBRAD_SOURCE_DIR "/samples/meshes/glossy_cornell.obj";
    std::vector<std::pair<std::string, std::string>> runs = {
        {"tool-solve", "vdbrad make cornell c.vdb --res 24 && vdbrad solve c.vdb o.vdb "
            "--directions 100 --tolerance 1e-4 --quiet"},
        {"tool-solve-50", "vdbrad make cornell c.vdb --res 24 && vdbrad solve c.vdb o.vdb "
            "--directions 100 --tolerance 0 --iterations 50 --quiet"},
        {"tool-solve-cloud", "vdbrad make slab s.vdb --res 12 && vdbrad solve-cloud s.vdb o.vdb "
            "--directions 60 --periodic --iterations 8 --quiet"},
        {"tool-solve-glossy", "vdbrad voxelize '" + glossyMesh + "' g.vdb --res 16 --quiet && "
            "vdbrad solve g.vdb o.vdb --directions 60 --iterations 4 --quiet"},
        {"tool-solve-cloud-ground", "vdbrad make slab s.vdb --res 12 && vdbrad solve-cloud s.vdb "
            "o.vdb --directions 60 --periodic --ground-albedo 0.4 --iterations 8 --quiet"},
        {"tool-solve-cloud-hg", "vdbrad make cumulus k.vdb --res 16 && vdbrad solve-cloud k.vdb "
            "o.vdb --directions 60 --g 0.7 --iterations 6 --quiet"},
    };
#ifdef VDBRAD_MPIEXEC
    // Two MPI ranks: direction subsets (surfaces, clouds) and slabs of the scene.
    const std::string mpirun = std::string("'") + VDBRAD_MPIEXEC
        + "' --oversubscribe --allow-run-as-root -np 2 '" + VDBRAD_CLI_PATH + "' ";
    runs.push_back({"tool-solve-2-ranks", "vdbrad make cornell c.vdb --res 24 && " + mpirun
        + "solve c.vdb o.vdb --directions 100 --tolerance 0 --iterations 20 --quiet"});
    runs.push_back({"tool-solve-2-slabs", "vdbrad make cornell c.vdb --res 24 && " + mpirun
        + "solve c.vdb o.vdb --directions 100 --tolerance 0 --iterations 20 --distribute slabs "
        "--quiet"});
    runs.push_back({"tool-solve-cloud-2-ranks", "vdbrad make cumulus k.vdb --res 16 && " + mpirun
        + "solve-cloud k.vdb o.vdb --directions 60 --iterations 6 --accelerate anderson --quiet"});
#endif
    const char* update = std::getenv("VDBRAD_UPDATE_GOLDEN");
    const std::map<std::string, std::string> golden = readGolden(kToolGoldenFile);
    std::ostringstream lines;
    for (const auto& [name, cmd] : runs) {
        std::system(("rm -f '" + path("o.vdb") + "'").c_str());
        const test::ToolResult r = sh(cmd);
        ASSERT_EQ(r.status, 0) << name << ": " << r.err;
        const std::string h = hex(hashFile(path("o.vdb")));
        if (update && std::string(update) == "1") {
            lines << name << " " << h << "\n";
            continue;
        }
        const auto it = golden.find(name);
        ASSERT_NE(it, golden.end()) << name << " is not in " << kToolGoldenFile;
        EXPECT_EQ(h, it->second) << name << ": the tool's output bits changed";
    }
    if (update && std::string(update) == "1") {
        std::ofstream out(kToolGoldenFile);
        out << lines.str();
        ASSERT_TRUE(out.good()) << "cannot write " << kToolGoldenFile;
    }
}
