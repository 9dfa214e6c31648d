// The request layer (vdbrad/request/): options read and checked once for every host, the plan,
// and a solve through a request giving the bits of the solver called directly.
#include "grids/CanonicalGrids.h"
#include "vdbrad/request/SharedOptions.h"
#include "vdbrad/sweep/DirectionSet.h"
#include "vdbrad/vdbrad.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

using namespace vdbrad;

namespace {

// Bits of every active value of a float or vec3s grid, in tree order.
template<typename GridT>
void
appendBits(const GridT& grid, std::vector<uint32_t>& out)
{
    for (auto it = grid.cbeginValueOn(); it; ++it) {
        const auto v = *it;
        const size_t n = sizeof v / sizeof(float);
        std::vector<uint32_t> b(n);
        std::memcpy(b.data(), &v, sizeof v);
        out.insert(out.end(), b.begin(), b.end());
    }
}

std::vector<uint32_t>
bits(const openvdb::GridBase::Ptr& grid)
{
    std::vector<uint32_t> out;
    if (const auto g = openvdb::gridPtrCast<openvdb::FloatGrid>(grid)) appendBits(*g, out);
    if (const auto g = openvdb::gridPtrCast<openvdb::Vec3SGrid>(grid)) appendBits(*g, out);
    EXPECT_FALSE(out.empty()) << grid->getName() << " is neither float nor vec3s, or empty";
    return out;
}

// The message of the OptionError @a f throws, or "" if it throws none.
template<typename F>
std::string
optionError(F&& f)
{
    try {
        f();
    } catch (const OptionError& e) {
        return e.what();
    }
    return "";
}

} // namespace

// Every message names options as its host spells them.
TEST(Request, MessagesSpellOptionsAsTheHostDoes)
{
    Request cli("solve", surfaceSolveOptions());
    Request py("solve", surfaceSolveOptions(), Spelling::Python);
    EXPECT_EQ(optionError([&] { cli.set("max-memory", "8X"); cli.bytes("max-memory", false); }),
        "--max-memory: '8X' is not a size (e.g. 8G, 512M, 1000000)");
    EXPECT_EQ(optionError([&] { py.set("max-memory", "8X"); py.bytes("max-memory", false); }),
        "max_memory: '8X' is not a size (e.g. 8G, 512M, 1000000)");
    EXPECT_EQ(optionError([&] { py.set("directions", "0"); }),
        "directions must be in [1, " + std::to_string(DirectionSet::maxCount()) + "], got 0");
    EXPECT_EQ(optionError([&] { py.set("update", "bogus"); }),
        "update must be jacobi, inplace or progressive, got 'bogus'");
    EXPECT_EQ(optionError([&] { py.set("directons", "3"); }),
        "unknown option 'directons' for 'solve'; did you mean 'directions'?");
    EXPECT_EQ(optionError([&] { cli.set("direction", "3"); }),
        "unknown option '--direction' for 'solve'; did you mean '--directions'?");
    Request gathered("solve", surfaceSolveOptions(), Spelling::Python);
    gathered.set("gather", "16");
    EXPECT_EQ(optionError([&] { SurfaceSolve s(gathered); }),
        "gather applies only to method montecarlo");
}

// Defaults come from the table; values read back as given; shaped values are checked.
TEST(Request, ReadsDefaultsAndShapedValues)
{
    Request r("solve-cloud", cloudSolveOptions());
    EXPECT_FALSE(r.has("sun"));
    EXPECT_EQ(r.numbers("sun", 2, "zenith,azimuth"), (std::vector<double>{0.0, 0.0}));
    r.set("sun", "60,30.5");
    EXPECT_EQ(r.numbers("sun", 2, "zenith,azimuth"), (std::vector<double>{60.0, 30.5}));
    EXPECT_EQ(r.autoOr("phase-order", 0, 32, "an order"), std::nullopt);
    r.set("phase-order", "6");
    EXPECT_EQ(r.autoOr("phase-order", 0, 32, "an order"), 6);
    r.set("max-memory", "1.5G");
    EXPECT_EQ(r.bytes("max-memory", false), 1.5 * 1024 * 1024 * 1024);
    r.set("sun", "60");
    EXPECT_EQ(optionError([&] { r.numbers("sun", 2, "zenith,azimuth"); }),
        "--sun needs 2 comma-separated numbers (zenith,azimuth), got '60'");
    r.set("periodic", "");
    EXPECT_TRUE(r.flag("periodic"));
    EXPECT_EQ(r.getInt("iterations"), 1000);
    EXPECT_EQ(r.getFloat("tolerance"), 1e-6);
}

// Options that contradict each other fail together, before any grid is read.
TEST(Request, ChecksOptionsTogether)
{
    Request r("solve", surfaceSolveOptions());
    r.set("distribute", "slabs");
    r.set("lines", "standard");
    EXPECT_EQ(optionError([&] { SurfaceSolve s(r); }), "--distribute slabs needs naive lines");
    Request c("solve-cloud", cloudSolveOptions());
    c.set("min-period", "8");
    EXPECT_EQ(optionError([&] { CloudSolve s(c); }),
        "--min-period applies to --periodic boxes only");
    Request u("solve", surfaceSolveOptions());
    u.set("irradiance", "3");
    EXPECT_EQ(optionError([&] { SurfaceSolve s(u); }), "--irradiance needs --sun");
    u.set("sun", "95,0");
    EXPECT_EQ(optionError([&] { SurfaceSolve s(u); }),
        "--sun: the zenith angle must be in [0, 90) degrees");
    u.set("sun", "30,0");
    u.set("direct", "sweep");
    EXPECT_EQ(optionError([&] { SurfaceSolve s(u); }),
        "--sun is computed exactly: it needs --direct exact or auto");
    Request k("solve", surfaceSolveOptions(), Spelling::Python);
    k.set("checkpoint-every", "3");
    EXPECT_EQ(optionError([&] { SurfaceSolve s(k); }),
        "checkpoint_every needs checkpoint FILE");
}

// A request solves with exactly the solver's bits, plans what the solver allocates, and refuses
// a solve past the memory limit before allocating.
TEST(Request, SolveGivesTheSolversBitsAndPlansItsMemory)
{
    grids::BuildParams p;
    p.res = 24;
    const openvdb::GridPtrVec grids = grids::makeCornell(p);
    Request r("solve", surfaceSolveOptions());
    r.set("directions", "120");
    r.set("visibility-cache", "0");
    const SolveResult result = solveSurfaces(grids, r);
    ASSERT_EQ(result.grids.size(), 1u);

    const Scene scene = buildScene(grids);
    RadiosityOptions o;
    o.directions = 120;
    o.visibilityCache = 0;
    EXPECT_EQ(bits(result.grids[0]), bits(solveRadiosity(scene, o)));
    EXPECT_TRUE(result.converged);
    EXPECT_EQ(result.iterations, result.grids[0]->metaValue<int32_t>("vdbrad:iterations"));

    EXPECT_EQ(result.plan.directions, int(DirectionSet::fromCount(120).size()));
    EXPECT_EQ(result.plan.solverBytes,
        double(RadiositySolver::memoryEstimate(scene, o, workerThreads())));
    EXPECT_GT(result.plan.secondsPerIteration, 0.0);

    r.set("max-memory", "1K");
    EXPECT_THROW(solveSurfaces(grids, r), MemoryLimitError);
}

// A cloud through its request: the solver's bits, the output grid named as asked.
TEST(Request, CloudSolveGivesTheSolversBits)
{
    grids::BuildParams p;
    p.res = 12;
    const openvdb::GridPtrVec grids = grids::makeCumulus(p);
    Request r("solve-cloud", cloudSolveOptions());
    r.set("sun", "30,0");
    r.set("directions", "60");
    r.set("output-name", "scatter");
    const SolveResult result = solveClouds(grids, r);
    // J and its scattered source (isotropic: the Y_00 coefficient alone), named after it.
    ASSERT_EQ(result.grids.size(), 2u);
    EXPECT_EQ(result.grids[0]->getName(), "scatter");
    EXPECT_EQ(result.grids[1]->getName(), "scatter_sh0");

    const Cloud cloud = buildCloud(grids);
    CloudTransferOptions o;
    o.sunZenith = 30.0;
    o.directions = 60;
    openvdb::GridPtrVec sources;
    EXPECT_EQ(bits(result.grids[0]), bits(solveCloud(cloud, o, nullptr, SolveControl(), nullptr,
        nullptr, &sources)));
    ASSERT_EQ(sources.size(), 1u);
    EXPECT_EQ(bits(result.grids[1]), bits(sources[0]));
}

// The time left follows the residual's trend: halving each second from 1e-2 to 1e-6 takes
// ceil(log2(1e4)) = 14 more iterations of one second.
TEST(Request, IterationEtaFollowsTheResidualsTrend)
{
    IterationEta eta(1e-6, 1000);
    EXPECT_FALSE(eta.secondsLeft());
    double r = 0.08;
    for (int k = 1; k <= 4; ++k, r /= 2) eta.add(k, r, 1.0);
    ASSERT_TRUE(eta.secondsLeft());
    EXPECT_DOUBLE_EQ(*eta.secondsLeft(), 14.0);   // residual now 1e-2
    IterationEta capped(1e-6, 6);
    r = 0.08;
    for (int k = 1; k <= 4; ++k, r /= 2) capped.add(k, r, 1.0);
    EXPECT_DOUBLE_EQ(*capped.secondsLeft(), 2.0);   // the cap comes first
}
