// Surfaces inside a medium (FogSurfaces.h, CloudTransferOptions::surfaces).
#include "vdbrad/cloud/CloudTransfer.h"
#include "vdbrad/cloud/FogSurfaces.h"
#include "vdbrad/core/Checkpoint.h"
#include "vdbrad/core/Constants.h"
#include "vdbrad/reference/MonteCarloSolver.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/surface/DirectLight.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "grids/CanonicalGrids.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <openvdb/openvdb.h>

#include <cmath>
#include <map>
#include <memory>

using namespace vdbrad;
using openvdb::Coord;

namespace {


class FogSurfacesTest : public ::testing::Test
{
protected:
    static void SetUpTestSuite() { openvdb::initialize(); }
};

// A uniform fog of extinction @a sigma (per world unit) and albedo @a omega over @a box (index
// space of @a transform).
Cloud
fog(const openvdb::math::Transform& transform, const openvdb::CoordBBox& box, double sigma,
    float omega)
{
    openvdb::FloatGrid::Ptr density = openvdb::FloatGrid::create(0.f);
    density->setName("density");
    density->setTransform(transform.copy());
    density->setGridClass(openvdb::GRID_FOG_VOLUME);
    density->tree().fill(box, float(sigma), true);
    density->tree().voxelizeActiveTiles();
    CloudOptions o;
    o.defaultAlbedo = omega;
    return buildCloud({density}, o);
}

} // namespace

// The furnace (grids::makeFurnaceBox: a closed cube shell of albedo rho, emission E) filled with
// fog, radiosity @a sigma per world unit and albedo @a omega, solved at defaults.
struct FoggyFurnace
{
    Scene scene;
    Cloud cloud;
    std::unique_ptr<CloudTransfer> transfer;

    FoggyFurnace(int res, double sigma, float omega, CloudTransferOptions o = {})
    {
        grids::BuildParams p;
        p.res = res;
        p.albedo = 0.5f;
        p.emission = 1.f;
        scene = buildScene(grids::makeFurnaceBox(p));
        const openvdb::CoordBBox shell = scene.voxels().bbox();
        cloud = fog(scene.transform(),
            openvdb::CoordBBox(shell.min() + Coord(1), shell.max() - Coord(1)), sigma, omega);
        o.surfaces = &scene;
        o.irradiance = 0.0;
        transfer.reset(new CloudTransfer(cloud, o));
    }
};

// A closed room of uniform albedo rho and emission E, with no absorption in it, holds a uniform
// isotropic radiance E / (pi (1 - rho)) (the furnace): every wall's radiosity is E / (1 - rho)
// and the fog's mean radiance E / (pi (1 - rho)), however thick the fog. The areas the lines see
// (FogSurfaces.h) make it exact up to the direction set's quadrature of the cosine: measured at
// res 24, every voxel's radiosity within -0.62 % / +0.06 %, the fog's mean radiance within
// -0.26 %, the area-weighted mean radiosity within 0.04 %; nothing leaves the room (the voxels
// closing its digital edges face a closed cavity: their lines out of the box are not theirs).
TEST_F(FogSurfacesTest, ClosedConservativeFurnaceIsExactVoxelByVoxel)
{
    for (double sigma : {1e-6, 1.0, 10.0}) {
        FoggyFurnace f(24, sigma, 1.f);
        CloudTransfer& t = *f.transfer;
        t.solve();
        ASSERT_TRUE(t.converged());
        const std::vector<float> B = t.surfaceRadiosity();
        ASSERT_EQ(B.size(), f.scene.size());
        double sum = 0.0, area = 0.0;
        for (size_t v = 0; v < B.size(); ++v) {
            const double a = t.surfaceArea()[v];
            sum += B[v] * a;
            area += a;
            ASSERT_NEAR(B[v], 2.0, 2.0 * 0.008) << "sigma " << sigma << " voxel " << v;
        }
        EXPECT_NEAR(sum / area, 2.0, 2.0 * 0.001) << sigma;
        for (float J : t.meanIntensity()) ASSERT_NEAR(J * kPi, 2.0, 2.0 * 0.004) << sigma;
        const CloudBudget& b = t.budget();
        EXPECT_NEAR(b.balance(), 0.0, 1e-5) << sigma;
        EXPECT_LT(b.albedo + b.transmittance, 1e-9) << sigma;
        EXPECT_NEAR(b.surfaceAbsorptance, 1.0, 1e-5) << sigma;
        EXPECT_EQ(b.emitted, 1.0);
    }
}

// An absorbing fog takes its share: the balance closes (emitted = absorbed by the fog and by the
// walls), and the walls' radiosity falls below the furnace's, more so in thicker fog.
TEST_F(FogSurfacesTest, AbsorbingFogBalancesEnergy)
{
    double before = 2.0;
    for (double sigma : {1.0, 10.0}) {
        FoggyFurnace f(24, sigma, 0.5f);
        CloudTransfer& t = *f.transfer;
        t.solve();
        const CloudBudget& b = t.budget();
        EXPECT_NEAR(b.balance(), 0.0, 1e-5) << sigma;
        EXPECT_NEAR(b.absorptance + b.surfaceAbsorptance, 1.0, 1e-5) << sigma;
        EXPECT_GT(b.absorptance, 0.1) << sigma;
        double sum = 0.0, area = 0.0;
        const std::vector<float> B = t.surfaceRadiosity();
        for (size_t v = 0; v < B.size(); ++v) {
            sum += B[v] * t.surfaceArea()[v];
            area += t.surfaceArea()[v];
        }
        EXPECT_LT(sum / area, before - 0.1) << sigma;
        before = sum / area;
    }
}

// The sun at the zenith on a floor under clear air: each floor voxel takes F0 per voxel face and
// the floor reflects rho times all of it (sum of B A); per voxel, B = rho F0 within the scatter
// of the areas the lines see (a digital line meets a floor it runs along in one voxel of
// several: measured up to +19 % away from the edges, +-4.5 % in the middle row).
TEST_F(FogSurfacesTest, SunlitFloorReflectsItsAlbedoTimesTheIrradiance)
{
    const int n = 16;
    openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(0.1);
    openvdb::MaskTree mask;
    for (int i = 0; i < n; ++i) for (int k = 0; k < n; ++k) mask.setValueOn(Coord(i, 0, k));
    VoxelIndex index(mask);
    const Scene floor(xform, index, std::vector<openvdb::Vec3f>(index.size(),
        openvdb::Vec3f(0.f, 1.f, 0.f)), Attribute(0.5f), Attribute(0.f), "normal",
        GridRoles::SurfaceKind::NormalGrid);
    const Cloud air = fog(*xform, openvdb::CoordBBox(Coord(0, 1, 0), Coord(n - 1, n, n - 1)),
        1e-6, 1.f);
    CloudTransferOptions o;
    o.surfaces = &floor;
    CloudTransfer t(air, o);
    t.solve();
    const std::vector<float> B = t.surfaceRadiosity();
    double reflected = 0.0;
    for (size_t v = 0; v < B.size(); ++v) {
        reflected += double(B[v]) * t.surfaceArea()[v];
        const Coord c = floor.voxels().coord(v);
        if (c.x() < 2 || c.x() > n - 3 || c.z() < 2 || c.z() > n - 3) continue;
        ASSERT_NEAR(B[v], 0.5, 0.5 * 0.25) << c;
    }
    EXPECT_NEAR(reflected, 0.5 * n * n, 0.5 * n * n * 1e-5);
    const CloudBudget& b = t.budget();
    EXPECT_NEAR(b.balance(), 0.0, 1e-6);
    // What the floor reflects leaves the box, up or through the sides, but 2.4e-4 of it
    // (lines leaving the floor's digital rim meet its edge voxels' backs).
    EXPECT_NEAR(b.albedo + b.transmittance, 0.5, 5e-4);
}

// Without fog, the transfer is a radiosity solver: on the Cornell box, against a Monte Carlo
// reference (MonteCarloSolver: continuous cosine-weighted rays, a final gather), wall by wall it
// is as close as the surface solver with its light swept too (RadiositySolver, DirectMode::Sweep).
TEST_F(FogSurfacesTest, FogFreeCornellAgreesWithMonteCarlo)
{
    grids::BuildParams p;
    p.res = 32;
    const openvdb::GridPtrVec g = grids::makeCornell(p);
    const Scene scene = buildScene(g);
    MonteCarloOptions mo;
    mo.samples = 256;
    mo.gather = 2048;
    auto mc = openvdb::gridPtrCast<openvdb::Vec3SGrid>(solveMonteCarlo(scene, mo).front());
    ASSERT_TRUE(mc);
    RadiosityOptions ro;
    ro.directions = 300;
    ro.direct = DirectMode::Sweep;
    const auto swept = openvdb::gridPtrCast<openvdb::Vec3SGrid>(solveRadiosity(scene, ro));
    ASSERT_TRUE(swept);
    // The room's air as a clear fog (make cornell --tau: not inside the blocks).
    p.tau = 1e-6f;
    Cloud air;
    for (const openvdb::GridBase::Ptr& grid : grids::makeCornell(p)) {
        if (grid->getName() == "density") air = buildCloud({grid});
    }
    ASSERT_GT(air.size(), 0u);
    CloudTransferOptions o;
    o.surfaces = &scene;
    o.irradiance = 0.0;
    o.directions = 300;
    openvdb::GridBase::Ptr radiosity;
    solveCloud(air, o, nullptr, SolveControl(), nullptr, &radiosity);
    const auto B = openvdb::gridPtrCast<openvdb::Vec3SGrid>(radiosity);
    ASSERT_TRUE(B);
    // Mean radiosity per wall (by its normal's dominant axis and sign) and channel.
    struct Sums { openvdb::Vec3d fog{0.0}, swept{0.0}, mc{0.0}; };
    std::map<int, Sums> walls;
    auto fcc = B->getConstAccessor();
    auto scc = swept->getConstAccessor();
    auto mcc = mc->getConstAccessor();
    for (size_t v = 0; v < scene.size(); ++v) {
        const openvdb::Vec3f n = scene.normal(v);
        int axis = 0;
        for (int k = 1; k < 3; ++k) if (std::abs(n[k]) > std::abs(n[axis])) axis = k;
        const int key = 2 * axis + (n[axis] > 0.f ? 1 : 0);
        const Coord c = scene.voxels().coord(v);
        walls[key].fog += openvdb::Vec3d(fcc.getValue(c));
        walls[key].swept += openvdb::Vec3d(scc.getValue(c));
        walls[key].mc += openvdb::Vec3d(mcc.getValue(c));
    }
    // Measured (res 32, 300 directions): the transfer -0.3 % to -14 % wall by wall (12.7 % mean
    // over the voxels), the surface solver -0.5 % to -9 % (9.7 %); both low where the small
    // lamp's light reaches through few directions (the surface solver's exact direct light is
    // within 2.5 %: not yet in fog).
    for (const auto& [key, sums] : walls) {
        for (int ch = 0; ch < 3; ++ch) {
            EXPECT_NEAR(sums.fog[ch] / sums.mc[ch], 1.0, 0.16) << "wall " << key << " " << ch;
            EXPECT_NEAR(sums.swept[ch] / sums.mc[ch], 1.0, 0.11) << "wall " << key << " " << ch;
        }
    }
}

// The same bits on any number of threads, and a checkpoint resumes the same solve.
TEST_F(FogSurfacesTest, ThreadsAndCheckpointsKeepTheBits)
{
    CloudTransferOptions o;
    o.directions = 60;
    o.maxIterations = 6;
    o.accelerate = Acceleration::Anderson;
    std::vector<float> reference;
    for (int threads : {1, 2, 8}) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
        FoggyFurnace f(12, 3.0, 0.8f, o);
        f.transfer->solve();
        std::vector<float> out = f.transfer->meanIntensity();
        const std::vector<float> B = f.transfer->surfaceRadiosity();
        out.insert(out.end(), B.begin(), B.end());
        if (reference.empty()) reference = out;
        else ASSERT_EQ(out, reference) << threads;
    }
    FoggyFurnace full(12, 3.0, 0.8f, o), resumed(12, 3.0, 0.8f, o);
    for (int i = 0; i < 3; ++i) full.transfer->iterate();
    SolverState state;
    full.transfer->saveState(state);
    for (int i = 0; i < 3; ++i) full.transfer->iterate();
    resumed.transfer->restoreState(state);
    for (int i = 0; i < 3; ++i) resumed.transfer->iterate();
    EXPECT_EQ(resumed.transfer->surfaceRadiosity(), full.transfer->surfaceRadiosity());
    EXPECT_EQ(resumed.transfer->meanIntensity(), full.transfer->meanIntensity());
    EXPECT_EQ(resumed.transfer->budget().balance(), full.transfer->budget().balance());
    EXPECT_EQ(resumed.transfer->fingerprint(), full.transfer->fingerprint());
}

// Surfaces are refused where the transfer cannot place them: periodic boxes, a ground, a
// scene on another transform.
TEST_F(FogSurfacesTest, RefusesWhatItCannotSolve)
{
    FoggyFurnace f(8, 1.0, 1.f);
    CloudTransferOptions o;
    o.surfaces = &f.scene;
    o.periodic = true;
    EXPECT_THROW(CloudTransfer(f.cloud, o), openvdb::ValueError);
    o.periodic = false;
    o.groundAlbedo = 0.3;
    EXPECT_THROW(CloudTransfer(f.cloud, o), openvdb::ValueError);
    o.groundAlbedo.reset();
    const Cloud shifted = fog(*openvdb::math::Transform::createLinearTransform(0.5),
        openvdb::CoordBBox(Coord(1), Coord(6)), 1.0, 1.f);
    EXPECT_THROW(CloudTransfer(shifted, o), openvdb::ValueError);
    o.channel = 1;   // a grey scene has one channel
    EXPECT_THROW(CloudTransfer(f.cloud, o), openvdb::ValueError);
}
// The closed sphere (grids::makeFurnaceSphere: curved walls, staircase normals) filled with a
// conservative fog: energy balances exactly; a staircase voxel met from the fog takes the light
// whatever its normal says, but some lines still reach a voxel's back past a digital corner or
// leave through the shell, so the walls fall a little short of the furnace's E / (1 - rho):
// measured at res 24, mean -1.2 %, voxels -16.7 % to -0.2 %, 0.23 % leaving the sphere (where
// the flat box is exact to 0.6 %). Before the fog side decided, backs took 3.5 %.
TEST_F(FogSurfacesTest, ClosedSphereFurnaceIsCloseToExact)
{
    grids::BuildParams p;
    p.res = 24;
    const Scene scene = buildScene(grids::makeFurnaceSphere(p));
    const openvdb::CoordBBox shell = scene.voxels().bbox();
    // Fog in the cells inside the shell: flood from the centre, stopping at surface voxels.
    openvdb::FloatGrid::Ptr density = openvdb::FloatGrid::create(0.f);
    density->setName("density");
    density->setTransform(scene.transform().copy());
    density->setGridClass(openvdb::GRID_FOG_VOLUME);
    {
        auto acc = density->getAccessor();
        const Coord mid = shell.min() + shell.max(); std::vector<Coord> todo{Coord(mid.x() / 2, mid.y() / 2, mid.z() / 2)};
        acc.setValue(todo[0], 1.f);
        while (!todo.empty()) {
            const Coord c = todo.back();
            todo.pop_back();
            for (int k = 0; k < 6; ++k) {
                Coord q = c;
                q[k / 2] += k % 2 ? 1 : -1;
                if (!shell.isInside(q) || acc.isValueOn(q) || scene.voxels().find(q) >= 0) continue;
                acc.setValue(q, 1.f);
                todo.push_back(q);
            }
        }
    }
    CloudOptions co;
    const Cloud cloud = buildCloud({density}, co);
    CloudTransferOptions o;
    o.surfaces = &scene;
    o.irradiance = 0.0;
    CloudTransfer t(cloud, o);
    t.solve();
    const std::vector<float> B = t.surfaceRadiosity();
    double sum = 0.0, area = 0.0;
    for (size_t v = 0; v < B.size(); ++v) {
        ASSERT_GT(B[v], 2.0 * (1.0 - 0.175)) << v;
        ASSERT_LT(B[v], 2.0) << v;
        sum += B[v] * t.surfaceArea()[v];
        area += t.surfaceArea()[v];
    }
    EXPECT_NEAR(sum / area, 2.0 * (1.0 - 0.012), 2.0 * 0.004);
    const CloudBudget& b = t.budget();
    EXPECT_NEAR(b.balance(), 0.0, 1e-5);
    EXPECT_LT(b.albedo + b.transmittance, 0.003);
}
