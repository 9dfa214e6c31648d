// FixedPointIteration and iterateSolve(): option checks, convergence bookkeeping, the Anderson
// step's physical-iterate rule, and driving a solve with checkpoints and reports, as the
// one-call solve functions and the tool do.
#include "vdbrad/cloud/CloudTransfer.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/reference/MonteCarloSolver.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/sweep/FixedPointIteration.h"

#include "CanonicalScene.h"

#include <gtest/gtest.h>

#include <openvdb/openvdb.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>

using namespace vdbrad;

namespace {

class IterationTest : public ::testing::Test
{
protected:
    static void SetUpTestSuite() { openvdb::initialize(); }
    std::string path(const std::string& name) const
    {
        return ::testing::TempDir() + "vdbrad_iteration_" + name;
    }
};

} // namespace

TEST_F(IterationTest, OptionsAreCheckedOnce)
{
    const double nan = std::numeric_limits<double>::quiet_NaN();
    EXPECT_THROW(FixedPointIteration(0, 1e-5, Acceleration::None, 1), openvdb::ValueError);
    EXPECT_THROW(FixedPointIteration(5, -1.0, Acceleration::None, 1), openvdb::ValueError);
    EXPECT_THROW(FixedPointIteration(5, nan, Acceleration::None, 1), openvdb::ValueError);
    EXPECT_THROW(FixedPointIteration(5, 0.0, Acceleration::Anderson, 0), openvdb::ValueError);
    EXPECT_NO_THROW(FixedPointIteration(5, 0.0, Acceleration::None, 0));   // depth unused
    // Every solver takes its checks from it.
    const Scene scene = test::canonicalScene("furnace-box", 6);
    RadiosityOptions r;
    r.maxIterations = 0;
    EXPECT_THROW(RadiositySolver(scene, r), openvdb::ValueError);
    MonteCarloOptions m;
    m.tolerance = nan;
    EXPECT_THROW(MonteCarloSolver(scene, m), openvdb::ValueError);
}

TEST_F(IterationTest, ConvergedAndFinishedFollowTheResiduals)
{
    FixedPointIteration it(3, 0.1, Acceleration::None, 1);
    EXPECT_FALSE(it.converged());
    EXPECT_FALSE(it.finished());
    EXPECT_EQ(it.iterate([] { return 0.5; }), 0.5);
    EXPECT_FALSE(it.finished());
    it.iterate([] { return 0.1; });   // at the tolerance: converged
    EXPECT_TRUE(it.converged());
    EXPECT_TRUE(it.finished());
    FixedPointIteration capped(2, 0.0, Acceleration::None, 1);
    capped.iterate([] { return 1.0; });
    capped.iterate([] { return 1.0; });
    EXPECT_FALSE(capped.converged());
    EXPECT_TRUE(capped.finished());   // at the cap
    EXPECT_EQ(capped.residuals(), (std::vector<double>{1.0, 1.0}));
    EXPECT_GE(capped.seconds(), 0.0);
    // Saved and restored: the same history.
    SolverState state;
    capped.save(state);
    FixedPointIteration back(2, 0.0, Acceleration::None, 1);
    back.restore(state);
    EXPECT_EQ(back.residuals(), capped.residuals());
    EXPECT_EQ(back.seconds(), capped.seconds());
    EXPECT_EQ(FixedPointIteration(2, 0.0, Acceleration::None, 1).makeMixer<float>(4), nullptr);
}

TEST_F(IterationTest, AndersonStepKeepsThePlainStepWhenTheMixedOneIsNotPhysical)
{
    // x -> G(x) = 0.5 x + 1 (fixed point 2), two unknowns. The first step is a plain one; the
    // second extrapolates to the fixed point exactly (an affine map of rank one).
    FixedPointIteration it(10, 0.0, Acceleration::Anderson, 4);
    auto mixer = it.makeMixer<double>(2);
    ASSERT_NE(mixer, nullptr);
    auto G = [](const double* x, double* gx) {
        for (int i = 0; i < 2; ++i) gx[i] = 0.5 * x[i] + 1.0;
    };
    double x[2] = {0.0, 0.0}, gx[2];
    for (int k = 0; k < 2; ++k) {
        G(x, gx);
        andersonStep(*mixer, x, gx, [](const double*) { return true; });
        std::memcpy(x, gx, sizeof x);
    }
    EXPECT_NEAR(x[0], 2.0, 1e-12);   // Anderson on an affine map: GMRES, exact in 2 steps
    // Refused: the plain step G(x) is kept and the history restarts.
    double y[2] = {10.0, 10.0}, gy[2];
    G(y, gy);
    andersonStep(*mixer, y, gy, [](const double*) { return false; });
    EXPECT_EQ(gy[0], 6.0);
    EXPECT_EQ(mixer->rejectedSteps(), 1u);
}

TEST_F(IterationTest, IterateSolveReportsCheckpointsAndResumesToTheSameBits)
{
    const Scene scene = test::canonicalScene("cornell", 16);
    RadiosityOptions o;
    o.directions = 60;
    o.maxIterations = 7;
    o.tolerance = 0.0;
    // Uninterrupted, with every report counted.
    RadiositySolver whole(scene, o);
    SolveControl c;
    std::vector<int> before, after;
    std::string described;
    int stoppedAt = 0;
    bool stoppedConverged = true;
    c.note = [&](const std::string& line) { described = line; };
    c.beforeIteration = [&](int k) { before.push_back(k); };
    c.afterIteration = [&](int k, double r) {
        after.push_back(k);
        EXPECT_EQ(r, whole.residuals().back());
    };
    c.stopped = [&](int k, double, bool converged) {
        stoppedAt = k;
        stoppedConverged = converged;
    };
    c.checkpoint = path("whole.ck");
    c.checkpointEvery = 3;
    std::remove(c.checkpoint.c_str());
    iterateSolve(whole, c);
    EXPECT_EQ(before, (std::vector<int>{1, 2, 3, 4, 5, 6, 7}));
    EXPECT_EQ(after, before);
    EXPECT_EQ(stoppedAt, 7);
    EXPECT_FALSE(stoppedConverged);
    EXPECT_EQ(described, whole.describe());
    EXPECT_NE(described.find("solving"), std::string::npos);

    // The checkpoint holds iteration 6 (every 3, not the last); resumed, a fresh solver
    // computes iteration 7's bits.
    RadiositySolver resumed(scene, o);
    SolveControl r;
    r.resume = c.checkpoint;
    std::vector<int> resumedIterations;
    r.beforeIteration = [&](int k) { resumedIterations.push_back(k); };
    iterateSolve(resumed, r);
    EXPECT_EQ(resumedIterations, (std::vector<int>{7}));
    ASSERT_EQ(resumed.rgb().size(), whole.rgb().size());
    EXPECT_EQ(std::memcmp(resumed.rgb().data(), whole.rgb().data(),
        whole.rgb().size() * sizeof(openvdb::Vec3f)), 0);
    std::remove(c.checkpoint.c_str());
}

TEST_F(IterationTest, CheckpointErrorsNameTheirFile)
{
    const Scene scene = test::canonicalScene("furnace-box", 6);
    RadiosityOptions o;
    o.directions = 20;
    RadiositySolver solver(scene, o);
    SolveControl c;
    c.resume = path("missing.ck");
    std::remove(c.resume.c_str());
    try {
        iterateSolve(solver, c);
        FAIL() << "a missing checkpoint was resumed";
    } catch (const CheckpointError& e) {
        EXPECT_NE(std::string(e.what()).find(c.resume + ": cannot open"), std::string::npos)
            << e.what();
    }
    // Another problem's checkpoint (a cloud's) is refused, naming the file.
    std::ofstream(path("bogus.ck")) << "VDBRADCK not really";
    c.resume = path("bogus.ck");
    EXPECT_THROW(iterateSolve(solver, c), CheckpointError);
    std::remove(c.resume.c_str());
    // Monte Carlo keeps no checkpoints: a control naming one is refused before any work.
    MonteCarloOptions m;
    m.samples = 4;
    SolveControl mc;
    mc.checkpoint = path("mc.ck");
    EXPECT_THROW(solveMonteCarlo(scene, m, nullptr, mc), openvdb::ValueError);
    SolveControl bad;
    bad.checkpointEvery = 0;
    EXPECT_THROW(iterateSolve(solver, bad), openvdb::ValueError);
}

TEST_F(IterationTest, OneCallSolvesMatchTheClasses)
{
    // solveRadiosity / solveCloud / solveMonteCarlo: the classes' solve(), bit for bit.
    const Scene scene = test::canonicalScene("furnace-sphere", 12);
    RadiosityOptions o;
    o.directions = 40;
    RadiositySolver solver(scene, o);
    solver.solve();
    const openvdb::FloatGrid::Ptr one =
        openvdb::gridPtrCast<openvdb::FloatGrid>(solveRadiosity(scene, o));
    ASSERT_TRUE(one);
    const openvdb::FloatGrid::Ptr cls = openvdb::gridPtrCast<openvdb::FloatGrid>(solver.grid());
    size_t voxels = 0;
    for (auto it = cls->cbeginValueOn(); it; ++it, ++voxels) {
        EXPECT_EQ(one->tree().getValue(it.getCoord()), *it);
    }
    EXPECT_EQ(voxels, scene.size());
    // The furnace: E / (1 - rho) = 2 within the tolerance's reach (1e-5 / (1 - rho)).
    for (auto it = one->cbeginValueOn(); it; ++it) EXPECT_NEAR(*it, 2.f, 1e-4f);

    grids::BuildParams p;
    p.res = 8;
    // (A cumulus: a slab, uniform sideways, solveCloud would solve one voxel deep.)
    const Cloud cloud = buildCloud(grids::findBuilder("cumulus")->build(p));
    CloudTransferOptions co;
    co.directions = 30;
    co.periodic = true;
    co.maxIterations = 5;
    CloudTransfer transfer(cloud, co);
    transfer.solve();
    const std::vector<float> J = transfer.meanIntensity();
    const openvdb::FloatGrid::Ptr grid =
        openvdb::gridPtrCast<openvdb::FloatGrid>(solveCloud(cloud, co));
    ASSERT_TRUE(grid);
    for (size_t i = 0; i < cloud.size(); ++i) {
        EXPECT_EQ(grid->tree().getValue(cloud.voxels().coord(i)), J[i]);
    }

    MonteCarloOptions m;
    m.samples = 8;
    m.maxIterations = 3;
    m.gather = 8;
    MonteCarloSolver mc(scene, m);
    mc.solve();
    mc.finalGather(8);
    const openvdb::GridPtrVec grids = solveMonteCarlo(scene, m);
    const openvdb::FloatGrid::Ptr b = openvdb::gridPtrCast<openvdb::FloatGrid>(grids.at(0));
    for (size_t i = 0; i < scene.size(); ++i) {
        EXPECT_EQ(b->tree().getValue(scene.voxels().coord(i)), mc.grey()[i]);
    }
}
